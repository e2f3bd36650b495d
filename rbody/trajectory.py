"""Trajectory: time first, then named observables; saved and loaded as .npz.

An observable may be given lazily, as a zero-argument callable returning its array: it is evaluated on
first access (trajectory[name], trajectory.data[name], save, final) and the result kept. A derived
observable (a pendulum's energy from theta and omega) then costs no memory until it is asked for: 10^6
batched rods with 101 samples hold 0.8 GB per observable. Its shape is checked when it is computed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from rbody.files import atomic_path


class Observables(Mapping):
    """name -> (T, ...) array; a value given as a zero-argument callable is evaluated on first access, its
    leading length checked against T, and kept (module docstring)."""

    def __init__(self, values: Mapping[str, Any], length: int) -> None:
        # another Observables: take its values as they stand, unevaluated ones still lazy
        self._values = dict(values._values if isinstance(values, Observables) else values)
        self._length = length
        for name, value in self._values.items():
            if not callable(value):
                self._check(name, value)

    def _check(self, name: str, value: Any) -> None:
        shape = value.shape if isinstance(value, np.ndarray) else np.shape(value)
        if shape[:1] != (self._length,):
            raise ValueError(f"observable {name!r} has shape {np.shape(value)}: must start with T={self._length}")

    def __getitem__(self, name: str) -> np.ndarray:
        value = self._values[name]
        if callable(value):
            value = value()
            self._check(name, value)
            self._values[name] = value
        return value

    def __contains__(self, name: object) -> bool:
        return name in self._values  # without evaluating

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def is_computed(self, name: str) -> bool:
        """False while observable `name` is a callable not yet evaluated."""
        return not callable(self._values[name])

    def __repr__(self) -> str:
        shown = {name: (np.shape(v) if not callable(v) else "lazy") for name, v in self._values.items()}
        return f"Observables({shown})"


@dataclass(frozen=True)
class Trajectory:
    """t (T,) [s]; data: name -> (T, *batch, ...) observable, or a zero-argument callable returning it
    (evaluated on first access and kept, see the module docstring); events: name -> array (event-driven
    scenes: event times, kinds, velocities after each event); meta: who produced it and how."""

    t: np.ndarray
    data: Mapping[str, np.ndarray | Callable[[], np.ndarray]]
    events: Mapping[str, np.ndarray] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=np.float64)
        if t.ndim != 1:
            raise ValueError(f"t has shape {t.shape}: expected (T,)")
        data = Observables(self.data, t.size)  # checks the arrays now, the callables when evaluated
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "events", dict(self.events))
        object.__setattr__(self, "meta", dict(self.meta))

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[name]
        except KeyError:
            raise KeyError(f"no observable {name!r}; this trajectory has {sorted(self.data)}") from None

    def __contains__(self, name: str) -> bool:
        return name in self.data

    @property
    def observables(self) -> tuple[str, ...]:
        return tuple(self.data)

    def final(self, name: str) -> np.ndarray:
        """Value of an observable at the last saved time."""
        return self[name][-1]

    def save(self, path: str | Path) -> Path:
        """Write t, observables (prefix 'data/'), events (prefix 'events/') and meta (JSON) to .npz."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(".npz")
        arrays = {"t": self.t}
        arrays.update({f"data/{k}": np.asarray(self[k]) for k in self.data})
        arrays.update({f"events/{k}": np.asarray(v) for k, v in self.events.items()})
        arrays["meta"] = np.array(json.dumps(self.meta, default=str))
        with atomic_path(path) as temporary:  # its name ends in .npz, so savez adds nothing
            np.savez(temporary, **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Trajectory":
        with np.load(Path(path), allow_pickle=False) as archive:
            data = {k[5:]: archive[k] for k in archive.files if k.startswith("data/")}
            events = {k[7:]: archive[k] for k in archive.files if k.startswith("events/")}
            meta = json.loads(str(archive["meta"])) if "meta" in archive.files else {}
            return cls(archive["t"], data, events, meta)
