"""`python -m validation export`: the MJCF of every scene of the main command, one file each."""

from __future__ import annotations

from pathlib import Path

import rbody
from rbody.files import write_atomic
from validation.cases import default_cases


def models() -> dict[str, str]:
    """case name -> MJCF text, for every case MuJoCo can express, at the case's MuJoCo time step."""
    from validation.backends import supports

    texts = {}
    for case in default_cases(quick=False):
        able, _why = supports(case.scene, "mujoco")
        if able:
            texts[case.name] = rbody.to_mjcf(case.scene, dt=case.dt.get("mujoco"))
    return texts


def export_models(out: Path) -> list[Path]:
    """Write <case>.xml for each model into `out`; returns the paths."""
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, text in models().items():
        path = out / f"{name}.xml"
        write_atomic(path, text)
        paths.append(path)
    return paths
