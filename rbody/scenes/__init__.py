"""The chapter's experiments: each a Scene factory whose scene carries its exact solution."""

from rbody.scenes.pendulum import compound_pendulum, swinging_rod

__all__ = ["compound_pendulum", "swinging_rod"]
