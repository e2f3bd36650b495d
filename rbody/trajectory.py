"""Trajectory: time first, then named observables; saved and loaded as .npz."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np


@dataclass(frozen=True)
class Trajectory:
    """t (T,) [s]; data: name -> (T, *batch, ...) observable; events: name -> array (event-driven
    scenes: event times, kinds, velocities after each event); meta: who produced it and how."""

    t: np.ndarray
    data: Mapping[str, np.ndarray]
    events: Mapping[str, np.ndarray] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=np.float64)
        if t.ndim != 1:
            raise ValueError(f"t has shape {t.shape}: expected (T,)")
        for name, value in self.data.items():
            if np.shape(value)[:1] != t.shape:
                raise ValueError(f"observable {name!r} has shape {np.shape(value)}: must start with T={t.size}")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "data", dict(self.data))
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
        arrays.update({f"data/{k}": np.asarray(v) for k, v in self.data.items()})
        arrays.update({f"events/{k}": np.asarray(v) for k, v in self.events.items()})
        arrays["meta"] = np.array(json.dumps(self.meta, default=str))
        np.savez(path, **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Trajectory":
        with np.load(Path(path), allow_pickle=False) as archive:
            data = {k[5:]: archive[k] for k in archive.files if k.startswith("data/")}
            events = {k[7:]: archive[k] for k in archive.files if k.startswith("events/")}
            meta = json.loads(str(archive["meta"])) if "meta" in archive.files else {}
            return cls(archive["t"], data, events, meta)
