"""Regenerate the README's animations: the chapter's scenes in motion, every engine side by side.

    python docs/make_animations.py              # docs/animations/*.gif, about 20 s on 2 cores
    python docs/make_animations.py --out DIR --format .webp

Runs the rolling race, the swinging rod near the top, the pi collisions (N = 2) and Newton's cradle in rbody,
MuJoCo and pymunk at the main command's settings (validation/cases.py) and draws them with rbody.animate
(validation/animations.py, the same animations as the main command's report). Prints the machine and versions,
then for each animation its frames, the stride chosen for its size budget, its size and the cost per frame.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # run from a checkout without installing


def main(argv: list[str] | None = None) -> int:
    from validation.animations import README_MAX_BYTES, chapter_animations
    from validation.baselines import versions
    from validation.machine import describe_machine

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=HERE / "animations", help="folder (default: docs/animations/)")
    parser.add_argument("--format", default=".gif", choices=(".gif", ".webp", ".mp4"), help="file format")
    parser.add_argument("--max-bytes", type=float, default=README_MAX_BYTES, help="size budget of each file")
    args = parser.parse_args(argv)
    print(f"machine: {describe_machine()}")
    print("versions: " + ", ".join(f"{k} {v}" for k, v in versions().items()))
    args.out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    written = chapter_animations(args.out, suffix=args.format, max_bytes=args.max_bytes, say=print)
    total = sum((args.out / name).stat().st_size for _caption, name in written)
    print(f"{len(written)} animations, {total / 1e6:.2f} MB in all, in {time.perf_counter() - started:.1f} s "
          f"(the runs included): {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
