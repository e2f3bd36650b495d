"""A constrained tree's run: each batch element by the scheme its method names, and the constraint observables.

simulate (rbody.simulation) hands a NativeModel with a constraint table here. method "rk4": the event-driven
scheme (rbody.engine.constraints.events); "moreau": the time-stepping scheme (rbody.engine.constraints.stepping);
"mujoco_euler", "implicitfast", "implicit": the same time-stepping with MuJoCo's integrator as its free motion.
Observables added to the tree's: constraint_force (T, *batch, rows) every row's force at each saved state (held
rows: their Lagrange multiplier, sliding friction -frictionloss sign v, free rows 0; columns named in
meta["constraint_rows"] as (kind, name, component)), constraint_error (T, *batch, rows) each row's error at
each saved state (an equality's residual [m or rad]: a loop's closure error; a limit's overshoot past its stop,
min(g, 0); 0 for friction), active_limits (T, *batch, limits) 1 where a limit holds the
joint (or tendon) at its stop (columns meta["limits"], a tendon's as "<tendon>.lower"), sticking (T, *batch,
frictions) 1 where a dof or a tendon with dry friction sticks (columns meta["frictions"]); with contacts (rbody.engine.contacts.observe) contacts (T, *batch) their count and
per candidate contact (columns meta["contacts"]) its distance, point, normal, normal and friction force; dissipated (T, *batch) [J] the energy dry friction, impacts and the joints' dampers have taken so far (the
energy observable plus dissipated is constant: the integrator's error aside, nothing else loses energy). The events of element b are in
trajectory.events (time, element, what, constraints, energy_lost) and meta["events"] counts them.
The time-stepping's constraint and contact observables, dissipated aside, are computed on first access from the
impulses its run kept (a short run that is asked for qpos alone pays for nothing else).
"""

from __future__ import annotations

import numpy as np

from rbody.engine.constraints import dynamics as dyn
from rbody.engine.constraints.events import EventRun
from rbody.engine.constraints.stepping import MODES, SCHEMES, MoreauRun, step_modes
from rbody.engine.constraints.table import CONTACT_KINDS, FRICTION_KINDS, UNILATERAL, ConstraintTable


def sample_rows(table: ConstraintTable, params: np.ndarray, samples: np.ndarray,
                modes: np.ndarray, slips: np.ndarray | None = None,
                forces_known: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(forces (S, rows), errors (S, rows)) at each saved state (S, n) in its mode (S, units): every row's force
    (runner docstring) and its error: an equality's residual [m or rad], a limit's overshoot past its stop min(g, 0),
    0 for friction rows. slips (S, units, 3): the sliding contacts' directions at each state (event-driven runs).
    forces_known: the run has its own forces (time-stepping: impulse / dt); forces are then None here and the
    errors come from the gaps alone (dynamics.state_gaps: no mass matrix, no Jacobian)."""
    p = np.array(params, dtype=np.float64)
    nq, nv, _n = dyn.sizes(p)
    a0, na = dyn.act_range(p)
    forces = None if forces_known else np.empty((samples.shape[0], table.rows))
    errors = np.empty((samples.shape[0], table.rows))
    qacc = np.empty(nv)
    q = np.empty(nq)
    codes = np.repeat(table.codes, table.unit_rows)  # each row's unit's
    from rbody.engine.multibody import _effective_qpos

    from rbody.engine.constraints.table import C_HEADER, U_SLIP, UNIT_SIZE

    for s in range(samples.shape[0]):
        p[table.mode_slice()] = modes[s]
        if slips is not None:
            for k in range(len(table.units)):
                start = table.offset + C_HEADER + UNIT_SIZE * k + U_SLIP
                p[start:start + 3] = slips[s, k]
        if forces_known:
            dyn.state_gaps(p, samples[s], errors[s], 0.0)  # errors read min(g, 0) only
            continue
        _effective_qpos(p, samples[s], q, 0)
        dyn.mode_accel(p, q, samples[s, nq:nq + nv], samples[s, a0:a0 + na], qacc, forces[s], errors[s])
    limits = np.isin(codes, UNILATERAL)
    errors[:, limits] = np.minimum(errors[:, limits], 0.0)
    errors[:, np.isin(codes, FRICTION_KINDS)] = 0.0
    normals = table.of_kinds(CONTACT_KINDS)
    if normals.any():  # a contact's normal row: its penetration min(g, 0); its tangent rows 0
        first = table.first_rows[normals]
        contact_rows = np.isin(codes, CONTACT_KINDS)
        kept = errors[:, first]
        errors[:, contact_rows] = 0.0
        errors[:, first] = np.minimum(kept, 0.0)
    return forces, errors


def run_constrained(description: str, model, method: str, dt: float, nsteps: int, save_every: int,
                    controls=None, observe=None):
    """Run every batch element of `model` (a NativeModel with constraints) by `method`; returns (t (S,), data
    (name -> (S, B, ...)), events (name -> (E,): time [s], element, what, constraints (the units' names, joined),
    energy_lost [J] and impulse [N s or N m s], the normal impulses of an impact summed over its units, 0 for mode
    changes), meta). controls: None (the controls are in the params rows, if
    any), or (at, control) with control(k, b, t, y) -> (nu,) the controls of element b written at params[at:] before
    step k (held through the step, its events included; rbody.control.step_controls). observe(t, out) the tree's
    observables of the saved states, default model.observe."""
    table: ConstraintTable = model.constraints
    y0, params = np.asarray(model.y0), np.asarray(model.params)
    batch = y0.shape[0]
    count = nsteps // save_every + 1
    out = np.empty((count, batch, y0.shape[1]))
    stepped = method in MODES  # time-stepping: its forces kept as nonzeros, modes and (S, rows) on first access
    modes = None if stepped else np.empty((count, batch, len(table.units)), dtype=np.int8)  # free, held, sliding...
    forces = None if stepped else np.empty((count, batch, table.rows))
    errors = None if stepped else np.empty((count, batch, table.rows))
    recorded = []  # the time-stepping's StepForces and its dry frictions' bounds, per element (not the run: its
    # parameter row, megabytes for a robot's file, is not kept past its element)
    events = {"time": [], "element": [], "what": [], "constraints": [], "energy_lost": [], "impulse": []}
    impacts = changes = 0
    for b in range(batch):
        if method in MODES:  # time-stepping: Moreau-Jean's free motion, or MuJoCo's integrator's
            run = MoreauRun(table, params[b], description, method)
        else:
            run = EventRun(table, params[b], description)
        hook = None
        if controls is not None:
            at, control = controls

            def hook(k, t, y, p, b=b, at=at, control=control):
                value = control(k, b, t, y)
                p[at:at + value.shape[0]] = value
        if stepped:  # the mean force of each step (impulse / dt); the modes and errors on first access
            out[:, b] = run.run(y0[b], dt, nsteps, save_every, hook)
            recorded.append((run.forces, run.friction_bounds))
        else:
            out[:, b], modes[:, b] = run.run(y0[b], dt, nsteps, save_every, hook)
            forces[:, b], errors[:, b] = sample_rows(table, params[b], out[:, b], modes[:, b], run.slips)
        impacts += run.log.impacts
        changes += run.log.mode_changes
        for event in run.log.events:
            events["time"].append(event.t)
            events["element"].append(b)
            events["what"].append(event.what)
            events["constraints"].append(", ".join(event.units))
            events["energy_lost"].append(event.energy_lost)
            events["impulse"].append(float(sum(event.impulse)))
    t = np.arange(count) * (dt * save_every)
    data = dict((model.observe if observe is None else observe)(t, out))
    limits = table.units_of_kinds(UNILATERAL)
    frictions = table.units_of_kinds(FRICTION_KINDS)
    if stepped:
        kept_modes: dict = {}

        def modes_at(b):  # element b's modes (S, units), read from its impulses once
            if b not in kept_modes:
                kept_modes[b] = step_modes(table, *recorded[b])
            return kept_modes[b]

        def all_forces():
            return np.stack([forces.dense() for forces, _bounds in recorded], axis=1)

        def all_errors():
            return np.stack([sample_rows(table, params[b], out[:, b], modes_at(b), forces_known=True)[1]
                             for b in range(batch)], axis=1)

        def rows_force(which):
            return np.stack([forces.columns(which) for forces, _bounds in recorded], axis=1)

        def pushing(which):
            return np.stack([forces.pushing(which) for forces, _bounds in recorded], axis=1)

        def modes_of(units, mode):
            return lambda: np.stack([modes_at(b)[:, units] == mode for b in range(batch)], axis=1)

        data["constraint_force"] = all_forces
        data["constraint_error"] = all_errors
        data["active_limits"] = modes_of(limits, 1)
        data["sticking"] = modes_of(frictions, 0)
    else:
        data["constraint_force"] = forces
        data["constraint_error"] = errors

        def rows_force(which):
            return forces[:, :, which]

        pushing = None
        data["active_limits"] = modes[:, :, limits] == 1
        data["sticking"] = modes[:, :, frictions] == 0
    data["dissipated"] = out[:, :, -1]
    contact_units = table.units_of_kinds(CONTACT_KINDS)
    if contact_units.size:
        from rbody.engine.contacts.observe import contact_observables

        data.update(contact_observables(table, params, out, rows_force, contact_units, pushing))
    meta = {"events": len(events["time"]), "impacts": impacts, "mode_changes": changes,
            "constraint_rows": table.labels(), "limits": table.names(limits), "frictions": table.names(frictions),
            "contacts": table.names(contact_units),
            "scheme": SCHEMES.get(method, "event-driven (rk4 between events)")}
    arrays = {"time": np.array(events["time"], dtype=float), "element": np.array(events["element"], dtype=int),
              "what": np.array(events["what"], dtype=str), "constraints": np.array(events["constraints"], dtype=str),
              "energy_lost": np.array(events["energy_lost"], dtype=float),
              "impulse": np.array(events["impulse"], dtype=float)}
    return t, data, arrays, meta


__all__ = ["run_constrained", "sample_rows"]
