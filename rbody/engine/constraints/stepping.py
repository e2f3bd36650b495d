"""The time-stepping scheme of the constraint layer (Moreau-Jean, with Anitescu-Potra's gap term), compiled.

For persistent or clustered events (a joint chattering against its stop, many limits at once, the contacts of
feet and grasps to come) locating every event is hopeless or pointless; the scheme then works with impulses over
a step h instead of forces at instants. From (q_k, v_k):

    v_free  = v_k + h M(q_k)^-1 f(q_k, v_k)                                 (f = passive - bias, gravity included)
    v_k+1   = v_free + M^-1 J^T P,        q_k+1 = q_k (+) h v_k+1            (symplectic Euler in the free motion)

with the impulses P solving one complementarity problem (rbody.engine.constraints.solver) over the rows
J = J(q_k): equalities J v_k+1 = 0 (bilateral); a limit touching its stop (g <= TOUCH_TOLERANCE), or with
restitution e > 0 and a gap that would close within the step (g + h J v_free < 0), by Newton's law
J v_k+1 + e min(J v_free, 0) >= 0, P >= 0, complementary (Moreau's impact law at the velocity level: the stop passed
within the step is restored by the projection below); a plastic limit (e = 0) whose gap would close within the
step by J v_k+1 + g / h >= 0, P >= 0, complementary (it reaches the stop at the end of the step, never beyond:
Anitescu and Potra's term); a dof (or a tendon) with dry friction
|P| <= frictionloss h, sticking (v_k+1 = 0) inside the box, sliding against it on its boundary. After the step the
configuration is projected onto the equalities and any stop it passed (rbody.engine.constraints.dynamics.project),
so neither drifts beyond round-off.

MuJoCo's integrators in the rigid limit (methods "mujoco_euler", "implicitfast", "implicit"; `mode` below): the
velocity update is the file's own integrator's (rbody.engine.mujoco_steps) with the impulses added,

    H (v_k+1 - v_k) = h f(q_k, v_k) + J^T P,      H = M - h D: D the joints' damping (mujoco_euler),
                                                  d(passive + actuator)/d qvel (implicitfast), with d bias / d qvel
                                                  (implicit)
    v_free = v_k + h H^-1 f,   v_k+1 = v_free + H^-1 J^T P,   q_k+1 = MuJoCo's mj_integratePos(q_k, v_k+1, h),

the problem of a step with the Delassus matrix J H^-1 J^T, and the activations advanced as MuJoCo advances them
(filterexact by the filter's exact solution). A servo's damping thus acts through H on the constrained motion as on
the free one: a stiff servo pushing a joint into its stop is held with the impulse h f, the force the closed form
gives. Where H is not symmetric (implicit's Coriolis derivative, implicitfast's lone free body: terms that vanish
at rest) the impulses take its symmetric part, (H + H^T) / 2, which keeps the step's problem a convex one (and M
where even that is not positive definite, an actuator whose force grows with the velocity). With no constraint active
a step is MuJoCo's step exactly (to round-off): rbody and MuJoCo then run the same scheme on a robot with limits,
friction or contacts and differ by the constraints' model (rigid here, soft there) only. Stable where MuJoCo's step
is: a stiff servo's damping is implicit.

Order 1 in h (an event falls inside a step). The problem of a step is solved exactly (mlcp_exact) when it has at
most EXACT_ROWS rows, else by projected Gauss-Seidel to STEP_TOLERANCE of the free velocities' scale, with at most
PGS_SWEEPS sweeps; a step whose problem is left with a larger residual fails the run (SimulationError naming the
time, the constraints and the residual). Stable, like symplectic Euler, on oscillations with h w < 2.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from numba import carray, njit

from rbody.engine import multibody as mb
from rbody.engine.actuation import next_activation
from rbody.engine.constraints import dynamics as dyn
from rbody.engine.elements import A_ACTADR, ACT_SIZE, X_ACT, X_ACTIVE, X_NU, extension_start
from rbody.engine.mujoco_steps import EULER, IMPLICIT, IMPLICITFAST, MUJOCO_METHODS, dof_parents, \
    euler_factor, integrate_positions, solve_general, step_matrices
from rbody.engine.constraints.jacobians import contact_unit_rows, contact_work_size, row_count, unit_at, unit_count
from rbody.engine.contacts.broadphase import (contact0, contact_row0, first_unit_at, kept_neighbours, kept_size,
                                              pair_at, pair_count, pair_reaches, pair_span)
from rbody.engine.contacts.kinematics import point_velocity
from rbody.engine.contacts.rows import GEOMETRY_WORK, candidate, kept_candidate, kept_exact, kept_for, pair_candidates
from rbody.engine.multibody import _effective_qpos
from rbody.engine.memory import cut, keep_alive, stack_floats, unowned
from rbody.engine.constraints.cone import (NORMAL, ROLL, ROUND_OFF, ROW, SPIN, TANGENT, cone_pgs, cone_polish,
                                           cone_residual, follow_drift, hold_states, inside_cones, magnitude,
                                           slide_polish, stick_polish, sticking_qp)
from rbody.engine.constraints.interior import interior_finish
from rbody.engine.constraints.natural_newton import states_newton
from rbody.engine.constraints.solver import (RANK_RTOL, cholesky_factor, lower_solve_into, lower_solve_rows_into,
                                             mlcp_exact_from, mlcp_pgs, natural_residual, upper_solve_into)
from rbody.engine.constraints.tree_factor import (dof_columns, gram_by_dofs, gram_of_few_dofs, product_by_dofs,
                                                  tree_solve_rows_into, tree_solve_supports_into)
from rbody.engine.mass_factor import tree_factor, tree_solve, tree_solve_transposed
from rbody.engine.constraints.islands import label_islands
from rbody.engine.constraints.kinds import is_dof_kind, is_equality_kind, is_friction_kind, is_stop_kind
from rbody.engine.constraints.table import (C_HEADER, CONTACT, CONTACT1, CONTACT_KINDS, FRICTION_KINDS, U_BODY1,
                                            U_BODY2, U_BOUND, U_DOF, U_KIND, UNILATERAL, UNIT_SIZE, U_RESTITUTION, U_ROLL,
                                            U_ROW0, U_ROWS, U_SPIN, ConstraintTable)
from rbody.errors import SimulationError

EXACT_ROWS = 64          # a step's problem with at most this many rows is solved exactly
STEP_TOLERANCE = 1e-10   # natural residual of PGS, relative to max(|b|, 1) [m/s or rad/s]
PGS_SWEEPS = 2000
CONE_ROUND = 50          # Gauss-Seidel sweeps between two exact finishes of a problem with contacts' cones
INTERIOR_AFTER = 1       # rounds of those before each further round also finishes from inside (interior_finish)
TOUCH_TOLERANCE = 1e-10  # [m or rad]
FLAGGED_GAP = TOUCH_TOLERANCE * 1e-3  # a stop or contact within this after a step (and pushing) is projected onto
SMALL_PROBLEM = 4096     # a step's W of at most this many entries is cut from its arena (step_arena), else allocated
SUPPORT_DOFS = 64        # a tree of more dofs takes each contact row on its support (its bodies' paths): below, a
                         # row of nv numbers is cheaper whole (contiguous, vectorised) than gathered
PROJECTION_ROUNDS = 6    # projections after a step, each with the stops the last one pushed past
MOREAU = -1              # mode of moreau_step: Moreau-Jean's own free motion, v + h M^-1 f
MODES = {"moreau": MOREAU, "mujoco_euler": EULER, "implicitfast": IMPLICITFAST, "implicit": IMPLICIT}
SCHEMES = {"moreau": "time-stepping (Moreau-Jean)",
           **{name: f"time-stepping (Moreau-Jean impulses, MuJoCo's {integrator} step as the free motion)"
              for name, integrator in zip(MUJOCO_METHODS, ("Euler", "implicitfast", "implicit"))}}


@njit(cache=True)
def mujoco_free_velocity(p, y, h, mode, M, f, vfree, L):
    """vfree (nv,) = v + h (M - h D)^-1 f: the free motion of MuJoCo's integrator `mode` (EULER, IMPLICITFAST,
    IMPLICIT) from the state y, with M (nv, nv) and f (nv,) at that state (module docstring); L (nv, nv) <- the lower
    Cholesky factor of the impulses' metric: the symmetric part of M - h D, or M where that is not positive
    definite."""
    nq, nv, _n = dyn.sizes(p)
    H = np.empty((nv, nv))
    if mode == EULER:  # D = -diag(the joints' damping): M and the rows already hold all of it
        do = int(p[mb.H_DOF])
        for a in range(nv):
            for c in range(nv):
                H[a, c] = M[a, c]
            H[a, a] = M[a, a] - h * -p[do + a * mb.DOF_SIZE + mb.D_DAMPING]
    else:
        matrices = np.empty((2, nv, nv))
        step_matrices(y, p, mode, p[extension_start(p) + X_ACTIVE] != 0.0, matrices)
        for a in range(nv):
            for c in range(nv):
                H[a, c] = M[a, c] - h * matrices[1, a, c]
    metric = np.empty((nv, nv))
    for a in range(nv):
        for c in range(nv):
            metric[a, c] = 0.5 * (H[a, c] + H[c, a])
    if not cholesky_factor(metric, L, 0.0, 0.0):
        cholesky_factor(M, L, 0.0, 0.0)
    rhs = f.copy()
    qacc = np.empty(nv)
    solve_general(H, rhs, qacc, nv)
    for d in range(nv):
        vfree[d] = y[nq + d] + h * qacc[d]


@njit(cache=True)
def cone_solve(W, b, lo, hi, role, mu, lam, tolerance, sweeps):
    """The step's problem with contacts' cones (rbody.engine.constraints.cone) from lam (a start, solved in place):
    CONE_ROUND Gauss-Seidel sweeps at a time, each round finished exactly (every contact sticking, by the box QP
    only where every friction is inside its bound; the states read from lam; a crawl along dependent rows taken to
    its end; then, where the interior finish below does not lower the residual, some sticking contacts made to
    slide), until the residual is 1e-3 of `tolerance`, or `sweeps` are spent, or a round within `tolerance` moves
    nothing (each after it would be the same); a start within `tolerance` (the last step's impulses, themselves
    finished) is kept where one sweep (from within 1e-3 of `tolerance`) or Newton's step on its states takes it
    to the round-off of its terms. From the INTERIOR_AFTER-th round on, each round not yet at 1e-3
    of `tolerance` also solves Tresca's problem from inside and finishes from its states (interior_finish: where
    dependent rows leave Gauss-Seidel crawling along W's null space), kept where that lowers the residual, the
    round then not counted as one that moved nothing and the next round going on from there. A start that no
    longer solves it is first tried on its own pieces (states_newton: a robot settling on its feet, the last step's
    sliding and sticking holding while b moves), kept where that reaches 1e-3 of `tolerance`. Returns the
    residual."""
    start = -1.0  # the warm start's residual, where taken (cone_pgs's first round starts from it)
    if np.any(lam != 0.0):
        start = cone_residual(W, b, lo, hi, role, mu, lam)
        if start > tolerance:
            held = states_newton(W, b, lo, hi, role, mu, lam, 1e-3 * tolerance)  # lam unchanged where it misses
            if held <= 1e-3 * tolerance:
                return held
    done = 0
    rounds = 0
    residual = np.inf
    normals = lam[:0]  # the interior finish's radii (its last barrier's impulses), from its first round on
    while done < sweeps:
        spent, residual = cone_pgs(W, b, lo, hi, role, mu, lam, tolerance, min(CONE_ROUND, sweeps - done), start)
        start = -1.0
        done += max(spent, 1)
        # a start within `tolerance` (the last step's finished impulses: a body at rest, a ball rolling) may solve it
        # to round-off: within 1e-3 of `tolerance`, one sweep takes up the round-off its velocities gathered since;
        # where that leaves it above round-off (dependent rows: condim 6 feet), or the start is above 1e-3 of
        # `tolerance` (which can lie below its terms' round-off: a five-box stack at dt = 0.1 gathers 2e-12 a step
        # where that is 1.8e-12, and was finished every other step, 0.6 to 1 ms each, where this takes 0.1),
        # Newton's step on the start's states (to 1e-14 there: a sweep's 5e-13 a step drifted the stack 2.4e-13 m
        # in 5 s); kept where that is round-off and no contact is at its cone's edge (there sliding at any speed is
        # Coulomb's too: the finishes below choose sticking), else finished below
        if spent == 0:
            trial = lam.copy()
            swept, round_off = np.inf, 0.0
            if residual <= 1e-3 * tolerance:
                _spent, swept = cone_pgs(W, b, lo, hi, role, mu, trial, 0.0, 1)
                round_off = ROUND_OFF * magnitude(W, b, trial)
            if swept > round_off:
                trial[:] = lam
                swept = hold_states(W, b, lo, hi, role, mu, trial)
                round_off = ROUND_OFF * magnitude(W, b, trial)
            if swept <= round_off and inside_cones(role, mu, trial):
                lam[:] = trial
                residual = swept
                break
        unswept = lam.copy() if spent == 0 else lam[:0]  # (Gauss-Seidel stops at `tolerance`: nothing to do)
        residual = min(stick_polish(W, b, lo, hi, role, mu, lam, 8), residual)
        if residual > 1e-3 * tolerance:
            residual = cone_polish(W, b, lo, hi, role, mu, lam, 4)
        # every contact sticking, dependent rows: the box QP by active sets, where every friction is inside its
        # bound (from a lam with one on its bound it reached the goal on none of 138 tries over 12 captured suites
        # of five robots, and took a tenth of those suites' time)
        if residual > 1e-3 * tolerance and inside_cones(role, mu, lam):
            residual = sticking_qp(W, b, lo, hi, role, mu, lam)
        if residual > 1e-3 * tolerance:  # dependent rows: Gauss-Seidel's crawl (a drift along W's null space to a
            residual = follow_drift(W, b, lo, hi, role, mu, lam)  # bound, a slow geometric tail) taken at once;
        if residual <= 1e-3 * tolerance:                          # the next round finishes from there
            break
        rounds += 1
        # Gauss-Seidel crawls (dependent rows): Tresca's problem from inside, its normals the next round's radii
        # (rbody.engine.constraints.interior); tried within `tolerance` too, where the drift's rounds would halve
        # the residual a round (the Go1 landing from its qpos0: 2e-11 to 7e-14 in 13 rounds, 20 ms; from inside,
        # 2e-16 at once), and from the first round on whose finishes failed (a quadruped settling on condim 6 feet
        # with dry friction in its joints: the second round's finishes repeat the first's, 1.6 ms of 3.5)
        if rounds >= INTERIOR_AFTER:
            if normals.size == 0:
                normals = lam.copy()
            trial = lam.copy()
            inside = interior_finish(W, b, lo, hi, role, mu, normals, trial, 1e-3 * tolerance)
            if inside < residual:
                lam[:] = trial
                residual = inside
                if residual <= 1e-3 * tolerance:
                    break
                continue  # the next round goes on from the interior finish's impulses
        # no stick state holds: some contacts slide (a capsule pivoting on a box's edge), tried where the interior
        # finish did not gain: on the quadrupeds' hard steps it never reached the goal (0 of 69 tries on five
        # captured suites) and cost a third to a half of their rounds' finishes, where the interior finish does
        residual = slide_polish(W, b, lo, hi, role, mu, lam, 4)
        if residual <= 1e-3 * tolerance:
            break
        if spent == 0 and np.array_equal(lam, unswept):  # within `tolerance`, and neither Gauss-Seidel nor a finish
            break                                        # moved lam: every round after would repeat this one
    return residual


@njit(cache=True)
def solve_cones(W, b, lo, hi, role, mu, lam, tolerance, sweeps):
    """The step's problem with contacts' cones from the warm start lam (the last step's impulses), solved in place
    by cone_solve, and once more from rest where that ends above `tolerance` (the warm start led Gauss-Seidel
    astray). Returns the residual."""
    residual = cone_solve(W, b, lo, hi, role, mu, lam, tolerance, sweeps)
    if residual > tolerance:
        lam[:] = 0.0
        residual = cone_solve(W, b, lo, hi, role, mu, lam, tolerance, sweeps)
    return residual


@njit(cache=True)
def solve_problem(W, b, lo, hi, role, mu, lam, cones, exact_rows, sweeps, tolerance):
    """The step's problem (W, b, lo, hi; role and mu: the contacts' cones, where `cones`) from the warm start lam,
    solved in place: by cone_solve's rounds where it has cones, else exactly up to exact_rows rows, else by
    Gauss-Seidel. Returns (status: 0 within `tolerance`, 1 not, UNBOUNDED, residual)."""
    if cones:  # Gauss-Seidel by blocks, each round finished exactly (rbody.engine.constraints.cone)
        residual = solve_cones(W, b, lo, hi, role, mu, lam, tolerance, sweeps)
        return (0 if residual <= tolerance else 1), residual
    if b.shape[0] <= exact_rows:
        status, _steps = mlcp_exact_from(W, b, lo, hi, lam)  # warm: the last step's impulses
        residual = natural_residual(W, b, lo, hi, lam)
        return (1 if status == 0 and residual > tolerance else status), residual
    _sweeps, residual = mlcp_pgs(W, b, lo, hi, lam, tolerance, sweeps)
    return (0 if residual <= tolerance else 1), residual


@njit(cache=True)
def _solve_islands(W, b, lo, hi, role, mu, lam, island, count, exact_rows, sweeps, tolerance):
    """solve_problem island by island (island (m,): each row's, 0 to count - 1; islands.label_islands): each its
    own problem, gathered from the whole and its impulses put back. Returns the first status not 0 (its island
    left as it stands, the others not tried), else 0, and the largest residual."""
    m = b.shape[0]
    order = np.empty(m, dtype=np.int64)  # the rows island by island, ascending within each
    first = np.zeros(count + 1, dtype=np.int64)
    for c in range(m):
        first[island[c] + 1] += 1
    for k in range(count):
        first[k + 1] += first[k]
    size = 0
    for k in range(count):
        size = max(size, first[k + 1] - first[k])
    filled = first[:count].copy()
    for c in range(m):
        order[filled[island[c]]] = c
        filled[island[c]] += 1
    floats = np.empty(size * size + 6 * size)  # one island's W, b, lo, hi, mu and lam
    roles = np.empty(size, dtype=np.int64)
    worst = 0.0
    for k in range(count):
        rows = order[first[k]:first[k + 1]]
        n = rows.size
        Wk = cut(floats, 0, (n, n))
        bk, lok, hik = cut(floats, n * n, n), cut(floats, n * n + n, n), cut(floats, n * n + 2 * n, n)
        muk, lamk = cut(floats, n * n + 3 * n, n), cut(floats, n * n + 4 * n, n)
        rolek = roles[:n]
        cones = False
        for x in range(n):
            c = rows[x]
            for z in range(n):
                Wk[x, z] = W[c, rows[z]]
            bk[x], lok[x], hik[x], muk[x], lamk[x], rolek[x] = b[c], lo[c], hi[c], mu[c], lam[c], role[c]
            cones = cones or role[c] > NORMAL
        status, residual = solve_problem(Wk, bk, lok, hik, rolek, muk, lamk, cones, exact_rows, sweeps, tolerance)
        for x in range(n):
            lam[rows[x]] = lamk[x]
        worst = max(worst, residual)
        if status != 0:
            return status, worst
    return 0, worst


@njit(cache=True)
def _drop_null_equalities(A, index, lo, hi, b, role, mu, m, rates, support, start, length, on_support):
    """The step's rows without the equality rows no impulse acts through: those whose column of A (M^-1/2 J^T) is
    below RANK_RTOL of the largest in W's scale (|A_c|^2), the round-off of a zero row (a connect's component across
    a planar loop: 1e-17 where the loop's rows are 0.05). Kept, Gauss-Seidel would divide their round-off residual
    by their round-off diagonal and push the other rows by an impulse of order one through their round-off
    coupling. The rows after them move up in place (A's columns, index, bounds, b, role, mu, their free rates and
    supports); returns the count. on_support: A's columns are 0 off their rows' supports (the tree's factor), which
    are then the only entries read."""
    nv = A.shape[0]
    top = 0.0
    size = np.empty(m)
    for c in range(m):
        size[c] = 0.0
        if on_support and length[c] >= 0:
            for x in range(length[c]):
                d = support[start[c] + x]
                size[c] += A[d, c] * A[d, c]
        else:
            for d in range(nv):
                size[c] += A[d, c] * A[d, c]
        top = max(top, size[c])
    kept = 0
    for c in range(m):
        if role[c] == ROW and lo[c] == -np.inf and hi[c] == np.inf and not size[c] > RANK_RTOL * top:
            continue
        if kept != c:
            for d in range(nv):
                A[d, kept] = A[d, c]
            index[kept], lo[kept], hi[kept], b[kept], role[kept], mu[kept] = index[c], lo[c], hi[c], b[c], role[c], mu[c]
            rates[kept], start[kept], length[kept] = rates[c], start[c], length[c]
        kept += 1
    return kept


@njit(cache=True)
def near_contacts(p, w, vfree, h, J, g, formed, kept, reuse):
    """The gaps g of the candidates of every pair whose bounding spheres may meet within the step, and the rows J of
    the contacts a step can involve: touching (g <= TOUCH_TOLERANCE) or closing within it (g + h n . (v_b - v_a) < 0
    at the contact point, the bodies moving with the free velocities vfree (nv,)), each such unit listed in formed
    (units - contact0,) int64, in unit order (a pair's candidates follow the last pair's). The others' rows of J and
    g are left as they were (the step reads the formed ones only): a model's far candidates (a humanoid's limbs
    against the floor in the air) cost a distance each, not a row of nv numbers, and a pair whose bounding spheres
    cannot meet within the step (contacts.broadphase.pair_reaches) not even that, nor a read of its candidates'
    unit records. After the step's kinematics in the workspace w (its velocities are then vfree's). kept: the
    geometry the last step's end found and the broad phase's neighbour list (broadphase.kept_size); reuse: whether
    the geometry was found at this configuration, its exact candidates then read, not found again. Returns (the rows
    of the units it formed, their count): the step's problem has at most these rows and those before the contacts."""
    # Every array below is handed to a helper for each near contact: as views numba does not count (memory.unowned,
    # the scratch on this function's stack), not an atomic add and its undoing per array and call.
    p, w, vfree, J, g, kept = unowned(p), unowned(w), unowned(vfree), unowned(J), unowned(g), unowned(kept)
    nq = int(p[mb.H_NQ])
    count = 0
    units = 0
    mb.velocities(p, vfree, w)
    normal, point = carray(stack_floats(3), 3), carray(stack_floats(3), 3)
    v_a, v_b = carray(stack_floats(3), 3), carray(stack_floats(3), 3)
    work = carray(stack_floats(GEOMETRY_WORK), GEOMETRY_WORK)
    size = contact_work_size(J.shape[1])
    rows_work = carray(stack_floats(size), size) if size <= mb.STACK_FLOATS else np.empty(size)  # (huge trees)
    pairs = pair_count(p)  # each pair's reach and motion, one buffer (on the stack where small)
    reach_owned = carray(stack_floats(2 * pairs), 2 * pairs) if 2 * pairs <= mb.STACK_FLOATS else np.empty(2 * pairs)
    reach, motion = cut(reach_owned, 0, pairs), cut(reach_owned, pairs, pairs)
    pair_reaches(p, w, h, reach, motion, kept_neighbours(p, kept))  # every geom's sphere; then the listed pairs'
    for i in range(pairs):
        if reach[i] > TOUCH_TOLERANCE:  # the broad phase: the pair can neither touch nor close within the step
            continue
        at = pair_at(p, i)
        first, slots, row0, width = pair_span(p, at)
        read = reuse and kept_exact(kept, nq, first)  # found exactly at the last step's end, at this configuration
        if not read:  # every candidate of the pair at once, its geoms posed once; beyond reach: their least gap
            pair_candidates(p, w, first_unit_at(p, at), work, TOUCH_TOLERANCE + motion[i])
        for j in range(slots):
            k, row = first + j, row0 + j * width
            u = unit_at(p, k)
            gap = kept_candidate(kept, nq, k, normal, point) if read else candidate(work, j, normal, point)
            g[row] = gap
            point_velocity(p, w, int(p[u + U_BODY2]), point, v_b)
            point_velocity(p, w, int(p[u + U_BODY1]), point, v_a)
            closing = (normal[0] * (v_b[0] - v_a[0]) + normal[1] * (v_b[1] - v_a[1])   # n . (v_b - v_a) there
                       + normal[2] * (v_b[2] - v_a[2]))
            if gap <= TOUCH_TOLERANCE or gap + h * closing < 0.0:  # its rows from the geometry just found
                contact_unit_rows(p, k, w, J, g, row, gap, normal, point, rows_work)
                formed[units] = k
                units += 1
                count += int(p[u + U_ROWS])
    keep_alive(reach_owned)  # read through views only
    return count, units


@njit(cache=True, inline="always")
def _row_dot_on(J, a, x, support, s0, k):
    """J[a] . x on the row's support support[s0:s0 + k] (ascending: the dense sum's order, without its zero terms), or
    over every dof where k < 0."""
    if k < 0:
        return _row_dot(J, a, x)
    total = 0.0
    for y in range(k):
        d = support[s0 + y]
        total += J[a, d] * x[d]
    return total


@njit(cache=True)
def _unit_support(p, u, support, top):
    """Writes at support[top:] the dofs a contact unit u's rows can be nonzero on: those of its two bodies and of
    every body above each (rbody.engine.constraints.jacobians._add_point_rows), ascending, each once. Returns their
    count, or -1 (nothing written) where support has no room for them."""
    bo = int(p[mb.H_BODY])
    count = 0
    for body in (int(p[u + U_BODY1]), int(p[u + U_BODY2])):
        i = body
        while i >= 0:
            count += int(p[bo + i * mb.BODY_SIZE + mb.B_NDOF])
            i = int(p[bo + i * mb.BODY_SIZE + mb.B_PARENT])
    if top + count > support.size:
        return -1
    k = 0
    for body in (int(p[u + U_BODY1]), int(p[u + U_BODY2])):
        i = body
        while i >= 0:
            b = bo + i * mb.BODY_SIZE
            for d in range(int(p[b + mb.B_DOF0]), int(p[b + mb.B_DOF0]) + int(p[b + mb.B_NDOF])):
                support[top + k] = d
                k += 1
            i = int(p[b + mb.B_PARENT])
    for x in range(1, k):  # ascending (a handful of dofs: insertion), then each once (shared ancestors)
        d = support[top + x]
        y = x - 1
        while y >= 0 and support[top + y] > d:
            support[top + y + 1] = support[top + y]
            y -= 1
        support[top + y + 1] = d
    kept = 0
    for x in range(k):
        if kept == 0 or support[top + x] != support[top + kept - 1]:
            support[top + kept] = support[top + x]
            kept += 1
    return kept


@njit(cache=True, inline="always")
def _unit_rate(p, u, kind, J, r0, x):
    """J[r0] . x for the first row r0 of unit u: a dof's stop or dry friction reads its row's one entry (the row is
    0 off its dof: a dog's 146 stops cost 146 products a step, not 146 x 85)."""
    if is_dof_kind(kind):
        d = int(p[u + U_DOF])
        return J[r0, d] * x[d]
    return _row_dot(J, r0, x)


@njit(cache=True)
def _dof_path(parent, dof, support, top):
    """Writes at support[top:] the dof and its ancestors, ascending: the support of a stop's or a dry friction's
    row on that dof, and of its column of L^-T J^T. Returns their count, or -1 (nothing written) where support has
    no room for them."""
    count = 0
    d = dof
    while d >= 0:
        count += 1
        d = parent[d]
    if top + count > support.size:
        return -1
    d = dof
    for x in range(count - 1, -1, -1):
        support[top + x] = d
        d = parent[d]
    return count


@njit(cache=True, inline="always")
def _row_dot(J, a, x):
    """J[a] . x: one row's rate (the step reads the rates of the rows it uses, not of every row: a model with many
    far contact candidates has many zero rows)."""
    total = 0.0
    for d in range(x.size):
        total += J[a, d] * x[d]
    return total


@njit(cache=True)
def next_activations(p, act, rates, h):
    """act (na,) advanced over h [s] at the rates (na,) of the step's start as MuJoCo's mj_advance does (its
    mj_nextActivation, clamped to actrange)."""
    E = extension_start(p)
    for i in range(int(p[E + X_NU])):
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        adr = int(p[r + A_ACTADR])
        if adr >= 0:
            act[adr] = next_activation(p, r, act[adr], rates[adr], h)


@njit(cache=True)
def step_arena(p):
    """(floats, ints): the memory of moreau_step's arrays whose sizes the model bounds (M^-1/2 J^T, and W where it
    has at most SMALL_PROBLEM entries, among them), allocated once by the loop and carved by every step
    (memory.cut): a step's thirty arrays of its own each cost an allocation, its release and two atomic reference
    counts (a quarter of a sphere's step on a plane)."""
    nq, nv, _n = dyn.sizes(p)
    rows = row_count(p)
    _at, na = dyn.act_range(p)
    floats = (2 * nv * nv + 3 * nv  # moreau_step's cuts in order: M, L; f, vfree, delta
              + rows * nv + 8 * rows  # J; jdot, g, jfree, lo, hi, b, mu, position_rows
              + nq + mb.workspace_size(p) + 6 * int(p[mb.H_BODIES])  # q, the tree's workspace, acc
              + na + pair_count(p)  # rates, least
              + 2 * rows + nv * rows + SMALL_PROBLEM)  # lam, jnow, A (nv, m <= rows), W where small
    ints = (unit_count(p) - contact0(p) + 3 * rows + pair_count(p)  # formed; index, role, flagged; near
            + nv + rows  # the dofs' parents, the rows' islands (M factored along the tree)
            + 2 * rows + 2 * support_room(p)  # the rows' supports (start, length; the dofs), A's columns by dof
            + nv + 1)  # (where those lists start)
    return np.empty(floats), np.empty(ints, dtype=np.int64)


@njit(cache=True, inline="always")
def support_room(p):
    """Room (int64 entries) for the step's rows' supports, and for A's nonzero columns listed by dof: 4 a row and 2 a
    dof (a contact of two free bodies: 12 dofs for its 3 rows); a step that needs more takes the dense path for the
    rows beyond (supports) or allocates (the lists)."""
    return 4 * row_count(p) + 2 * int(p[mb.H_DOFS])


@njit(cache=True)
def moreau_step(p, y, h, P, exact_rows, sweeps, tolerance, problem_rows, mode, end_geometry, floats, ints):
    """One step of the scheme (module docstring) of the state y (n,) (phi all zero) in place, h [s], its free motion
    Moreau-Jean's own (mode MOREAU) or MuJoCo's integrator `mode` (EULER, IMPLICITFAST, IMPLICIT). P (rows,)
    gets every row's impulse [N s or N m s] (0 for rows not in the problem) and problem_rows (rows + 1,) int64 the
    rows of the step's problem (their count, then the rows, ascending); on entry both are the last step's (zeros
    before the first step: P is cleared on the rows problem_rows lists, not read elsewhere, since a model's far
    contact candidates are nearly all its rows). Returns (status, residual, rows in the problem): status 0 done, 1
    the complementarity problem left a residual above the tolerance, 2 the configuration could not be projected
    onto the equalities, UNBOUNDED (-1) the equalities contradict. The budget: exactly when it has at most
    exact_rows rows, else at most `sweeps` Gauss-Seidel sweeps to `tolerance` (relative to max(|b|, 1)).
    end_geometry (broadphase.kept_size): the contacts' geometry the last step's end found, read where this step
    starts at its configuration, and this step's, kept for the next, then the broad phase's neighbour list (zeros
    before the first step). floats, ints: step_arena's memory, which the step's arrays are cut from (its contents
    on entry are not read)."""
    # The arguments, handed to most helpers of the step, as views numba does not count (memory.unowned)
    p, y, P, end_geometry = unowned(p), unowned(y), unowned(P), unowned(end_geometry)
    nq, nv, n = dyn.sizes(p)
    rows = row_count(p)
    at, na = dyn.act_range(p)
    M, L = cut(floats, 0, (nv, nv)), cut(floats, nv * nv, (nv, nv))
    top = 2 * nv * nv
    f, vfree, delta = cut(floats, top, nv), cut(floats, top + nv, nv), cut(floats, top + 2 * nv, nv)
    top += 3 * nv
    J = cut(floats, top, (rows, nv))  # a contact's rows are formed only where it touches or closes within the step
    top += rows * nv  # (near_contacts), and only those are read (a quadruped's 23,838 rows of 18 numbers)
    jdot, g = cut(floats, top, rows), cut(floats, top + rows, rows)  # (each unit's rows set where formed, and only
    jfree, lo = cut(floats, top + 2 * rows, rows), cut(floats, top + 3 * rows, rows)
    hi = cut(floats, top + 4 * rows, rows)
    b, mu = cut(floats, top + 5 * rows, rows), cut(floats, top + 6 * rows, rows)  # those read)
    position_rows = cut(floats, top + 7 * rows, rows)
    top += 8 * rows
    q = cut(floats, top, nq)
    w = cut(floats, top + nq, mb.workspace_size(p))
    top += nq + mb.workspace_size(p)
    acc = cut(floats, top, (int(p[mb.H_BODIES]), 6))
    top += 6 * int(p[mb.H_BODIES])
    rates, least = cut(floats, top, na), cut(floats, top + na, pair_count(p))  # least: each contact pair's least
    top += na + pair_count(p)                                                     # gap at the end (state_gaps)
    lam_at, jnow_at, a_at = top, top + rows, top + 2 * rows  # the problem's arrays (m <= rows): lam, jnow, A (nv,
    w_at = a_at + nv * rows                                  # m), then W (m, m) where small (step_arena's layout)
    c0 = contact0(p)
    formed = cut(ints, 0, unit_count(p) - c0)  # the contacts formed (a list: a model's far candidates unread)
    index, role = cut(ints, unit_count(p) - c0, rows), cut(ints, unit_count(p) - c0 + rows, rows)
    flagged = cut(ints, unit_count(p) - c0 + 2 * rows, rows)  # the rows flagged in position_rows, in flag order
    near = cut(ints, unit_count(p) - c0 + 3 * rows, pair_count(p))  # (not a model's far candidates' rows)
    top_int = unit_count(p) - c0 + 3 * rows + pair_count(p)
    parent, island = cut(ints, top_int, nv), cut(ints, top_int + nv, rows)  # (the tree's factor only)
    top_int += nv + rows
    room = support_room(p)  # each problem row's support: support[start[c]:start[c] + length[c]] (length -1: dense)
    start, length = cut(ints, top_int, rows), cut(ints, top_int + rows, rows)
    support, columns = cut(ints, top_int + 2 * rows, room), cut(ints, top_int + 2 * rows + room, room)
    first = cut(ints, top_int + 2 * rows + 2 * room, nv + 1)  # (A's columns by dof: columns[first[d]:first[d + 1]])
    used = 0  # support's entries taken
    _effective_qpos(p, y, q, 0)
    # (with the activations' rates at the step's start, advanced by explicit Euler below as MuJoCo's Euler does)
    dyn.snapshot(p, q, y[nq:nq + nv], y[at:at + na], M, f, J, jdot, g, w, acc, None, False, False, rates)
    dyn.add_sliding_friction(p, f, J)
    v = y[nq:nq + nv]
    # L: the factor of the impulses' metric, which moves the velocities by metric^-1 J^T P. Moreau's, M, and MuJoCo's
    # Euler's, M + h diag(damping), factored along the tree (mass_factor: L^T L, no fill-in); implicitfast's and
    # implicit's densely. Each as its integrator's own step solves: a step with no constraint active is its to the bit
    tree = False  # (a pivot not positive: the dense factor below runs and reports it)
    if mode == MOREAU or mode == EULER:
        dof_parents(p, parent)
        tree = tree_factor(M, parent, L) if mode == MOREAU else euler_factor(p, M, h, parent, L)
    sparse = tree and nv > SUPPORT_DOFS  # (the rows on their supports: their products cost those, not nv each)
    if tree:  # vfree = v + h L^-1 L^-T f
        for d in range(nv):
            vfree[d] = f[d]
        tree_solve_transposed(L, parent, vfree)
        tree_solve(L, parent, vfree)
        for d in range(nv):
            vfree[d] = v[d] + h * vfree[d]
    elif mode == MOREAU:  # (a pivot not positive: LAPACK's factor reports it)
        L[:, :] = np.linalg.cholesky(M)
        lower_solve_into(L, f, vfree)  # M^-1 f, in place
        upper_solve_into(L, vfree, vfree)
        for d in range(nv):
            vfree[d] = v[d] + h * vfree[d]
    else:
        mujoco_free_velocity(p, y, h, mode, M, f, vfree, L)
    more, touching = near_contacts(p, w, vfree, h, J, g, formed, end_geometry, kept_for(end_geometry, q))
    bound = contact_row0(p) + more  # the problem's rows (at most the rows formed): their rates at the free
    role[:bound] = 0  # velocities (jfree), rows (index), bounds, b, roles and friction coefficients, supports
    mu[:bound] = 0.0
    if sparse:
        length[:bound] = -1  # (every dof, but a contact's, its bodies' paths, and a dof's row's, that dof's)
    cones = False
    m = 0
    units = unit_at(p, 0)  # (unit k's record from the first's: unit_at's reads from the header, redone each pass)
    for c in range(c0 + touching):  # the units before the contacts, then the contacts formed, in unit order
        k = c if c < c0 else formed[c - c0]
        u = units + k * UNIT_SIZE
        kind = int(p[u + U_KIND])
        r0, r = int(p[u + U_ROW0]), int(p[u + U_ROWS])
        m_before = m
        if is_equality_kind(kind):
            for a in range(r0, r0 + r):
                jfree[m] = _row_dot(J, a, vfree)
                index[m], lo[m], hi[m], b[m] = a, -np.inf, np.inf, jfree[m]
                m += 1
        elif is_stop_kind(kind):
            e = p[u + U_RESTITUTION]
            rate = _unit_rate(p, u, kind, J, r0, vfree)
            jfree[m] = rate
            if g[r0] <= TOUCH_TOLERANCE or (e > 0.0 and g[r0] + h * rate < 0.0):
                index[m], lo[m], hi[m] = r0, 0.0, np.inf
                b[m] = rate + e * min(rate, 0.0)
                m += 1
            elif g[r0] + h * rate < 0.0:
                index[m], lo[m], hi[m], b[m] = r0, 0.0, np.inf, rate + g[r0] / h
                m += 1
        elif is_friction_kind(kind):
            box = p[u + U_BOUND] * h
            jfree[m] = _unit_rate(p, u, kind, J, r0, vfree)
            index[m], lo[m], hi[m], b[m] = r0, -box, box, jfree[m]
            m += 1
        elif kind == CONTACT or kind == CONTACT1:  # a contact: its normal as a limit's row, its cone with it
            e = p[u + U_RESTITUTION]
            touching = g[r0] <= TOUCH_TOLERANCE
            dofs = _unit_support(p, u, support, used) if sparse else -1  # its rows' support (-1: every dof)
            rate = _row_dot_on(J, r0, vfree, support, used, dofs)
            if touching or g[r0] + h * rate < 0.0:
                if sparse:
                    for a in range(m, m + r):
                        start[a], length[a] = used, dofs
                    used += max(dofs, 0)
                jfree[m] = rate
                index[m], lo[m], hi[m] = r0, 0.0, np.inf
                if touching or e > 0.0:
                    b[m] = rate + e * min(rate, 0.0)
                else:
                    b[m] = rate + g[r0] / h
                m += 1
                role[m - 1] = NORMAL
                if kind == CONTACT:  # tangents, then spin and rolling (condim 4, 6): cone's roles in order
                    for t in range(1, r):
                        jfree[m] = _row_dot_on(J, r0 + t, vfree, support, used - max(dofs, 0), dofs)
                        index[m], lo[m], hi[m], b[m] = r0 + t, -np.inf, np.inf, jfree[m]
                        role[m] = NORMAL + t
                        mu[m] = (p[u + U_BOUND] if role[m] == TANGENT else p[u + U_SPIN] if role[m] == SPIN
                                 else p[u + U_ROLL] if role[m] == ROLL else 0.0)
                        m += 1
                    cones = True
        if sparse and m > m_before and is_dof_kind(kind):  # a stop's or dry friction's row on its dof's path
            dofs = _dof_path(parent, int(p[u + U_DOF]), support, used)
            if dofs >= 0:
                start[m_before], length[m_before] = used, dofs
                used += dofs
    status = 0
    residual = 0.0
    if m > 0:
        A = cut(floats, a_at, (nv, m))
        if sparse:  # L^-T J^T (M = L^T L), as sparse as J's rows: each column on its row's support
            tree_solve_supports_into(L, parent, J, index, m, A, support, start, length)
        elif tree:
            tree_solve_rows_into(L, parent, J, index, m, A)
        else:  # L^-1 J^T (M = L L^T)
            lower_solve_rows_into(L, J, index, m, A)  # M^-1/2 J^T: W = A^T A
        kept = _drop_null_equalities(A, index, lo, hi, b, role, mu, m, jfree, support, start, length, sparse)
        if kept < m:  # (a copy only where a row went)
            A = np.ascontiguousarray(A[:, :kept])
        m = kept
    lam = cut(floats, lam_at, m)
    for c in range(m):  # the last step's impulses: the warm start of Gauss-Seidel
        lam[c] = P[index[c]]
    for c in range(problem_rows[0]):  # then cleared on the last step's rows, the only ones set (not every row:
        P[problem_rows[1 + c]] = 0.0  # a quadruped's 24,822, nearly all its far contact candidates')
    problem_rows[0] = m
    for c in range(m):
        problem_rows[1 + c] = index[c]
    if m > 0:
        W = cut(floats, w_at, (m, m)) if m * m <= SMALL_PROBLEM else np.empty((m, m))
        islands = 1
        if sparse:  # W, and the rows' islands: those sharing no dof with the others (islands.py), from A's nonzero
            listed = dof_columns(A, m, support, start, length, first, columns)  # columns listed by dof
            if listed > columns.size:  # (more than the arena's room: their own memory)
                columns = np.empty(listed, dtype=np.int64)
                dof_columns(A, m, support, start, length, first, columns)
            gram_by_dofs(A, m, W, first, columns, island)
            islands = label_islands(island, role, m)
        elif tree:
            gram_of_few_dofs(A, m, W, columns, island)
            islands = label_islands(island, role, m)
        else:
            np.dot(A.T, A, W)  # (BLAS's product into W: A.T @ A's bits)
        bb, ll, hh = b[:m], lo[:m], hi[:m]  # (the solvers read them only)
        for c in range(m):
            lam[c] = min(max(lam[c], ll[c]), hh[c])
        scale = 1.0
        for c in range(m):
            scale = max(scale, abs(bb[c]))
        if islands == 1:
            status, residual = solve_problem(W, bb, ll, hh, role[:m], mu[:m], lam, cones, exact_rows, sweeps,
                                             tolerance * scale)
        else:
            status, residual = _solve_islands(W, bb, ll, hh, role[:m], mu[:m], lam, island, islands, exact_rows,
                                              sweeps, tolerance * scale)
        if status != 0:
            return status, residual, m
        x = delta  # the velocities' change M^-1 J^T lam (delta's memory, read below only after it is spent)
        if sparse:
            product_by_dofs(A, lam, first, columns, x)
        else:
            np.dot(A, lam, x)
        if tree:
            tree_solve(L, parent, x)
        else:
            upper_solve_into(L, x, x)
        jnow = cut(floats, jnow_at, m)  # the problem's rows' rates before the step
        for c in range(m):
            jnow[c] = _row_dot_on(J, index[c], v, support, start[c], length[c] if sparse else -1)
        loss = 0.0
        for c in range(m):
            P[index[c]] = lam[c]
        for d in range(nv):
            v[d] = vfree[d] + x[d]
        for c in range(m):
            after = _row_dot_on(J, index[c], v, support, start[c], length[c] if sparse else -1)
            if role[c] != ROW:  # contacts: the work of the impulse at the mean of the velocities before and after
                # the step (Kelvin's theorem; before it, not after the free motion, so that a contact that holds a
                # body at rest does no work against the velocity gravity gave it within the step)
                loss -= 0.5 * lam[c] * (after + jnow[c])
            elif lo[c] > -np.inf:  # limits and friction: the kinetic energy their impulse took
                loss -= 0.5 * lam[c] * (after + jfree[c])
        y[n - 1] += loss
    else:
        for d in range(nv):
            v[d] = vfree[d]
    y[n - 1] += h * dyn.damping_power(p, v)
    for d in range(nv):
        delta[d] = h * v[d]
    if mode == MOREAU:
        dyn.displace(p, y, delta)
    else:
        integrate_positions(p, y[:nq], v, h)
    if na and mode == MOREAU:
        for i in range(na):
            y[at + i] += h * rates[i]
        dyn.clamp_activations(p, y[at:at + na])
    elif na:
        next_activations(p, y[at:at + na], rates, h)
    # positions onto the equalities and onto every stop passed or touched (a projection in the metric of M moves
    # every dof: a stop it pushes past joins the set, and the projection is repeated), velocities onto the equalities
    # position_rows: 1 on a flagged row, 0 on the others the flagging reads: those before the contacts, and a near
    position_rows[:contact_row0(p)] = 0.0  # pair's normal rows, zeroed where it is first near
    near[:] = 0
    count = 0
    velocity_rows = position_rows[:0]  # the equalities' rows (rows,), from the first equality met (most have none)
    worst = 0.0
    for _round in range(PROJECTION_ROUNDS):
        dyn.state_gaps(p, y, g, FLAGGED_GAP, end_geometry, least)
        grown = False  # a row newly flagged (nothing flagged at all: no projection, the step stands as it is)
        for k in range(c0):
            u = units + k * UNIT_SIZE
            kind = int(p[u + U_KIND])
            r0, r = int(p[u + U_ROW0]), int(p[u + U_ROWS])
            if is_equality_kind(kind):
                if velocity_rows.size == 0:
                    velocity_rows = np.zeros(rows)
                for a in range(r0, r0 + r):
                    velocity_rows[a] = 1.0
                    if position_rows[a] == 0.0:
                        grown = True
                        position_rows[a] = 1.0
                        flagged[count] = a
                        count += 1
            elif is_stop_kind(kind) and _newly_flagged(g, P, position_rows, r0):
                position_rows[r0] = 1.0
                flagged[count] = r0
                count += 1
                grown = True
        for i in range(pair_count(p)):  # contacts: their normal rows, where the pair's least gap allows
            if least[i] > FLAGGED_GAP:
                continue
            _first, slots, row0, width = pair_span(p, pair_at(p, i))
            if near[i] == 0:
                near[i] = 1
                for j in range(slots):
                    position_rows[row0 + j * width] = 0.0
            for j in range(slots):
                if _newly_flagged(g, P, position_rows, row0 + j * width):
                    position_rows[row0 + j * width] = 1.0
                    flagged[count] = row0 + j * width
                    count += 1
                    grown = True
        if not grown:
            break
        worst, live = 0.0, 0  # every flagged row already within the projection's tolerance, no equality: the
        for c in range(count):  # projection would change nothing (the list kept to the rows still flagged: one a
            a = flagged[c]      # projection found apart is no longer)
            if position_rows[a] != 0.0:
                flagged[live] = a
                live += 1
                worst = max(worst, abs(g[a]))
        count = live
        held = velocity_rows
        if velocity_rows.size == 0:  # no equality
            if worst <= dyn.PROJECTION_TOLERANCE:
                break
            held = np.zeros(rows)  # no velocity row
        dense = np.zeros(rows)  # the flagged rows as project reads them, every row set
        for c in range(count):
            dense[flagged[c]] = 1.0
        worst, _speed = dyn.project(p, y, dense, held)
        for c in range(count):  # a row the projection found apart (geometry.APART) is no longer flagged
            position_rows[flagged[c]] = dense[flagged[c]]
    if worst > 1e3 * dyn.PROJECTION_TOLERANCE:
        return 2, worst, m
    return 0, residual, m


@njit(cache=True, inline="always")
def _newly_flagged(g, P, position_rows, r0):
    """Whether a unilateral row r0 joins the projection: within FLAGGED_GAP of its stop, not yet flagged, and past
    it or pushing."""
    return g[r0] <= FLAGGED_GAP and position_rows[r0] == 0.0 and (g[r0] < 0.0 or P[r0] > 0.0)


@njit(cache=True)
def _record(P, problem_rows, s, starts, rows, values, used):
    """The nonzero impulses of P (rows,) as saved sample s: appended to rows and values (grown by doubling when
    full), starts[s + 1] their end. Returns (rows, values, used). Read on the step's rows alone (problem_rows:
    count, then the rows, ascending; P is 0 elsewhere). Counted first, then copied: a scan whose loop may replace
    the arrays it writes costs numba 9 ns a row."""
    count = 0
    for c in range(problem_rows[0]):
        if P[problem_rows[1 + c]] != 0.0:
            count += 1
    if used + count > rows.size:
        size = rows.size
        while used + count > size:
            size *= 2
        grown_rows, grown_values = np.empty(size, dtype=np.int64), np.empty(size)
        grown_rows[:used], grown_values[:used] = rows[:used], values[:used]
        rows, values = grown_rows, grown_values
    _append_nonzeros(P, problem_rows, rows, values, used)
    used += count
    starts[s + 1] = used
    return rows, values, used


@njit(cache=True)
def _append_nonzeros(P, problem_rows, rows, values, used):
    """rows[used:], values[used:] the nonzeros of P (rows,) on problem_rows' rows, in order (room for them is
    there)."""
    for c in range(problem_rows[0]):
        a = problem_rows[1 + c]
        if P[a] != 0.0:
            rows[used], values[used] = a, P[a]
            used += 1


@njit(cache=True)
def moreau_loop(p, y0, h, nsteps, save_every, out, exact_rows, sweeps, tolerance, problem_rows, mode):
    """nsteps steps from y0 (n,); out (S, n) every save_every-th state (out[0] = y0). Returns (failed step or -1, its
    status, its residual, its rows, starts (S + 1,), rows, values): the impulses of the step that ended at each saved
    state as nonzeros (sample s's: rows[starts[s]:starts[s + 1]] and values there; a model's far contact candidates
    push nothing, and a dense (S, rows) record of a hand's 11,718 rows over 10 s held gigabytes)."""
    y = y0.copy()
    rows = row_count(p)
    P = np.zeros(rows)
    end_geometry = np.zeros(kept_size(p))
    out[0] = y
    starts = np.zeros(out.shape[0] + 1, dtype=np.int64)
    kept, values, used = np.empty(max(64, 4 * out.shape[0]), dtype=np.int64), np.empty(max(64, 4 * out.shape[0])), 0
    floats, ints = step_arena(p)
    for k in range(1, nsteps + 1):
        status, residual, m = moreau_step(p, y, h, P, exact_rows, sweeps, tolerance, problem_rows, mode,
                                          end_geometry, floats, ints)
        if status != 0:
            return k, status, residual, m, starts, kept[:used], values[:used]
        for a in range(y.shape[0]):
            if not np.isfinite(y[a]):
                return k, 3, 0.0, m, starts, kept[:used], values[:used]
        if k % save_every == 0:
            kept, values, used = _record(P, problem_rows, k // save_every, starts, kept, values, used)
            out[k // save_every] = y
    return -1, 0, 0.0, 0, starts, kept[:used], values[:used]


class StepForces:
    """The mean forces (impulse / dt [N or N m]) of the steps ending at each saved state of one time-stepping run,
    kept as nonzeros: sample s's rows rows[starts[s]:starts[s + 1]], values there. dense() (S, rows) every row's;
    columns(which) (S, len(which)) those rows' alone."""

    def __init__(self, starts: np.ndarray, rows: np.ndarray, impulses: np.ndarray, row_count: int, dt: float) -> None:
        self.starts, self.rows, self.impulses, self.dt = starts, rows, impulses, dt
        self.row_count = row_count
        self.samples = starts.size - 1

    @cached_property
    def sample_of(self) -> np.ndarray:
        """(nonzeros,) the sample each kept impulse belongs to."""
        return np.repeat(np.arange(self.samples), np.diff(self.starts))

    def pushing(self, which) -> np.ndarray:
        """(S,) how many of rows `which` have a positive impulse at each sample (distinct rows)."""
        chosen = np.zeros(self.row_count, dtype=bool)
        chosen[np.asarray(which, dtype=np.int64)] = True
        kept = chosen[self.rows] & (self.impulses > 0)
        return np.bincount(self.sample_of[kept], minlength=self.samples)

    def dense(self) -> np.ndarray:
        out = np.zeros((self.samples, self.row_count))
        out[self.sample_of, self.rows] = self.impulses / self.dt
        return out

    def columns(self, which, impulses: bool = False) -> np.ndarray:
        """(S, len(which)) the forces of rows `which` (impulses: their impulses [N s or N m s] instead)."""
        unique, inverse = np.unique(np.asarray(which, dtype=np.int64), return_inverse=True)
        column = np.full(self.row_count, -1, dtype=np.int64)
        column[unique] = np.arange(unique.size)
        out = np.zeros((self.samples, unique.size))
        kept = column[self.rows] >= 0
        out[self.sample_of[kept], column[self.rows[kept]]] = self.impulses[kept] if impulses else \
            self.impulses[kept] / self.dt
        return out[:, inverse.ravel()]


class MoreauRun:
    """The time-stepping run of one batch element (rbody.engine.constraints.runner): run(y0, dt, nsteps, save_every)
    -> samples (S, n); forces (StepForces) the impulses of the step ending at each sample divided by dt (its mean
    force); friction_bounds (frictions,) the dry frictions' bounds on a step's impulse, from which with the forces
    step_modes reads each unit's mode at each sample when asked for; log: impacts and mode changes are not events
    here."""

    def __init__(self, table: ConstraintTable, params: np.ndarray, description: str, method: str = "moreau") -> None:
        from rbody.engine.constraints.events import EventLog

        self.method = method
        self.mode = MODES[method]  # the free motion: Moreau-Jean's own, or MuJoCo's integrator's
        self.table = table
        self.p = np.array(params, dtype=np.float64)
        self.p[table.mode_slice()][table.of_kinds(FRICTION_KINDS)] = 0.0  # a view: the frictions' modes, sticking
        self.description = description
        self.log = EventLog()
        self.forces = None
        self.friction_bounds = None

    def run(self, y0, dt: float, nsteps: int, save_every: int, before_step=None) -> np.ndarray:
        """before_step(k, t, y, p): called before step k (0-based) to write its controls into the params row p, or
        None (one compiled loop); with it the steps are taken one by one, each as moreau_loop takes it."""
        count = nsteps // save_every + 1
        out = np.empty((count, len(y0)))
        problem_rows = np.zeros(self.table.rows + 1, dtype=np.int64)  # the last step's (moreau_step)
        if before_step is None:
            failed, status, residual, m, starts, rows, values = moreau_loop(
                self.p, np.array(y0, dtype=np.float64), dt, nsteps, save_every, out, EXACT_ROWS, PGS_SWEEPS,
                STEP_TOLERANCE, problem_rows, self.mode)
        else:
            failed, status, residual, m, starts, rows, values = self._stepwise(
                np.array(y0, dtype=np.float64), dt, nsteps, save_every, out, problem_rows, before_step)
        if failed >= 0:
            what = {1: f"the step's complementarity problem ({m} rows) was left with a residual above "
                       f"{STEP_TOLERANCE:g} of its scale (solver budget: exact up to {EXACT_ROWS} rows, else "
                       f"{PGS_SWEEPS} Gauss-Seidel sweeps)",
                    2: "the configuration could not be projected onto the equalities (they contradict each other "
                       "or the loop cannot close)",
                    -1: "the equalities contradict each other (no impulse makes them hold)",
                    3: "a non-finite state; try a smaller dt"}[status]
            in_problem = set(problem_rows[1:1 + problem_rows[0]].tolist())
            named = [u for u in self.table.units if u.row0 in in_problem] or list(self.table.units)
            names = ", ".join(repr(u.name) for u in named)
            raise SimulationError(f"scene {self.description}: method {self.method!r} with dt={dt}: at t={failed * dt:.9g} s, "
                                  f"constraints {names}: {what}; residual {residual:.3g}")
        self.forces = StepForces(starts, rows, values, self.table.rows, dt)
        frictions = self.table.units_of_kinds(FRICTION_KINDS)  # their bounds on a step's impulse [N s or N m s]
        self.friction_bounds = self.p[self.table.offset + C_HEADER + UNIT_SIZE * frictions + U_BOUND] * dt
        return out

    def _stepwise(self, y, dt, nsteps, save_every, out, problem_rows, before_step):
        """moreau_loop's steps one by one, before_step called before each (the same steps, the impulses carried and
        recorded as the loop carries and records them)."""
        P = np.zeros(self.table.rows)
        end_geometry = np.zeros(kept_size(self.p))
        out[0] = y
        starts = np.zeros(out.shape[0] + 1, dtype=np.int64)
        kept, values, used = np.empty(max(64, 4 * out.shape[0]), dtype=np.int64), np.empty(max(64, 4 * out.shape[0])), 0
        floats, ints = step_arena(self.p)
        for k in range(1, nsteps + 1):
            before_step(k - 1, (k - 1) * dt, y, self.p)
            status, residual, m = moreau_step(self.p, y, dt, P, EXACT_ROWS, PGS_SWEEPS, STEP_TOLERANCE, problem_rows,
                                              self.mode, end_geometry, floats, ints)
            if status != 0:
                return k, status, residual, m, starts, kept[:used], values[:used]
            if not np.all(np.isfinite(y)):
                return k, 3, 0.0, m, starts, kept[:used], values[:used]
            if k % save_every == 0:
                kept, values, used = _record(P, problem_rows, k // save_every, starts, kept, values, used)
                out[k // save_every] = y
        return -1, 0, 0.0, 0, starts, kept[:used], values[:used]


def step_modes(table: ConstraintTable, forces: StepForces, friction_bounds: np.ndarray) -> np.ndarray:
    """(S, units) int8, each unit's mode at each sample of a time-stepping run, read from the impulses it kept
    (forces) and its dry frictions' bounds on a step's impulse (frictions,) [N s or N m s]: a stop or contact held (1)
    where its first row pushes, else free (0); a dry friction sticking (0) inside its bound, else sliding against its
    impulse (-+1); an equality always held (1)."""
    rows, values = forces.rows, forces.impulses
    modes = np.zeros((forces.samples, len(table.units)), dtype=np.int8)  # a hand's 3,954 units over 10 s
    # stops and contacts: held (1) where their first row pushes, read from the nonzeros alone
    unit_of = table.unit_of_first_row[rows]
    stops = table.of_kinds(UNILATERAL + CONTACT_KINDS)
    frictions = table.of_kinds(FRICTION_KINDS)
    pushes = (unit_of >= 0) & (values > 0)
    pushes[pushes] = stops[unit_of[pushes]]
    modes[forces.sample_of[pushes], unit_of[pushes]] = 1
    sliding = table.units_of_kinds(FRICTION_KINDS)  # sticking (0) inside the bound, else sliding against it
    if sliding.size:
        value = forces.columns(table.first_rows[sliding], impulses=True)  # (S, frictions)
        modes[:, sliding] = np.where(np.abs(value) < friction_bounds * (1 - 1e-9), 0.0, -np.sign(value))
    modes[:, ~(stops | frictions)] = 1  # equalities: always held
    return modes


__all__ = ["moreau_step", "step_arena", "moreau_loop", "MoreauRun", "StepForces", "step_modes", "EXACT_ROWS", "STEP_TOLERANCE", "PGS_SWEEPS", "MODES", "SCHEMES",
           "mujoco_free_velocity", "next_activations"]
