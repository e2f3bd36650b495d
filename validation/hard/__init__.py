"""The numerical-stability suite: hard cases that break naive engines, run on rbody, MuJoCo, pymunk, Pinocchio and Bullet.

    python -m validation hard [--quick] [--out DIR] [--case N ...]

Each case exposes one failure mode (issue 6): the pi collisions to many digits, the swinging rod
near the top, free rotation near the intermediate axis, needles and thin discs, rolling at the
friction limit, too large a step, meshes at bad scales, long chains, time reversal, and (issue 22)
contacts in the rigid limit (a sphere thrown sliding, a block on an incline at its friction
boundary, a ball dropped with restitution, a box and a stack of boxes at rest). Every case runs
on every backend that can express it and gives rows of one table:

    outcome   exact (a count exact, or an error at round-off) | error (a finite run, its error
              given) | wrong count | blew up (a non-finite or unstable state, reported as an error)
              | refused (an error before any work, or a simulator that cannot express the case)
              | not run (beyond the time budget; the estimate is in the note)
    value     the measured error or count, `measure` says which
    rbody     pass / FAIL: whether rbody met the case's requirement (rbody rows only); the other
              simulators' rows are findings, reported and never judged against a loose bound

The cases live in validation/hard/contact.py (1, 5), motion.py (2, 3), shapes.py (4, 7), steps.py (6, 9),
chains.py (8) and rigid_contacts.py (10); their figures in figures.py. DIR/hard.md holds the
tables, the figures and each case's findings; the machine, the package versions and the wall time
head it.

The modules, each importing only those above it: rows (a row, a case's result, the outcome of a run
that raised), kit (what every time-stepped case measures: a backend's run timed by its stepping,
rbody's verdict, zero crossings, energy bounds), figures, the cases (contact, motion, shapes, steps,
chains, rigid_contacts), suite (the case table, the command and hard.md).
"""
