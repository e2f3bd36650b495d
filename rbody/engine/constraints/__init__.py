"""The constraint layer: joint limits, dry joint friction, equalities and contacts between geoms held rigidly.

What is modelled (rbody.layout: Joint.range, Joint.frictionloss, Joint.restitution, Tendon.range,
Tendon.frictionloss, Tendon.restitution, Equality) is the rigid limit of MuJoCo's soft constraints: a limit is a
unilateral constraint that the joint never passes by more than round-off; dry friction is Coulomb's law per degree
of freedom, exact stick and exact slip; an equality (a loop closed by a connect or a weld, a joint coupling) holds
to round-off; an impact on a limit obeys Newton's law with the joint's restitution e (0 by default: the joint stays
at its stop). A tendon's limits, its dry friction and a tendon equality are the same rows with the tendon's length
L(q) in place of a joint's coordinate (J = dL/dq; table.py, tendon_rows.py): a rope that goes taut, a cable that
sticks, fingers coupled through their tendons.

The problem. With the mass matrix M(q), the generalised forces f = passive - bias and the constraint rows J (their
kinds in table.py, their Jacobians in jacobians.py), the forces lambda on the rows solve a mixed complementarity
problem in w = J qacc + J' v (at the acceleration level, between impacts) or w = J v+ + e J v- (at the velocity
level, at impacts and over a time step), W = J M^-1 J^T:

    equalities:  w = 0;   limits: lambda >= 0, w >= 0, lambda w = 0;   dry friction: |lambda| <= F, w = 0 inside,
    lambda = -F sign(w) on the boundary

(solver.py). Drake (SAP; TAMSI), MuJoCo and Siconos pose the same problem. MuJoCo and Drake's SAP regularise it
into a strictly convex program (a constraint becomes a spring-damper in constraint space: solref/solimp, a
relaxation time), which is robust and smooth but lets joints pass their stops, friction creep and loops open under
load; TAMSI regularises friction by a Stribeck-like stiction speed. Siconos solves the complementarity problem
itself, event-driven or time-stepped (Moreau-Jean). rbody takes Siconos's road: the rigid problem, solved to a
stated tolerance, so that the divergence of a soft model from the rigid limit can be measured on a user's model.

The scheme, in this order and for this reason:

1. Event-driven where events are isolated (simulate(..., method="rk4"), the default; events.py). Between events
   the mode is fixed (which limits hold, which dofs stick; every equality holds), and the constrained dynamics
   (dynamics.py: M qacc = f + J^T lambda, J qacc + J' v = 0, by Cholesky and a minimum-norm solve that accepts
   redundant rows) is integrated by classical Runge-Kutta (order 4) on the sampling grid, each step followed by the
   projection of q and v onto the held rows' manifold (Newton's method in the metric of M), so that a loop's
   closure error stays at round-off rather than drifting as Baumgarte's springs would let it. Events are located
   exactly, by Brent's method on the length of the step that crossed a guard: a limit reached (its distance g = 0),
   a held limit released (its force lambda = 0), a sticking dof's required friction force reaching frictionloss, a
   sliding dof's velocity crossing zero. At an event, impacts are solved by Newton's law of restitution as a
   complementarity problem over the touching limits and the equalities, then the new mode by the complementarity
   problem at the acceleration level (exact active-set solver). Why: where events are isolated this keeps the
   integrator's order through them (the closed forms of the tests hold to 1e-9 and better), with the event times
   exact to the step map's round-off, as rbody's impact scenes (rbody.engine.events) already do for collisions.
2. Time-stepping where events persist or cluster (method="moreau"; stepping.py): Moreau-Jean's scheme with
   Anitescu-Potra's gap term, impulses over each step from one complementarity problem (exact active set up to
   stepping.EXACT_ROWS rows, else projected Gauss-Seidel to stepping.STEP_TOLERANCE), order 1, no event located;
   the projection after each step keeps equalities and stops at round-off. Why: a chattering joint, a ball coming
   to rest by infinitely many bounces (Zeno), the many contacts of feet and grasps would stop an event-driven run;
   a time-stepped one passes through them at a cost per step independent of the number of events.
3. The same time-stepping with MuJoCo's integrator as its free motion (method="mujoco_euler", "implicitfast",
   "implicit"; stepping.py): H (v' - v) = h f + J^T P with H = M - h D the file's own step matrix. Why: published
   robots run stiff position servos at a step only an implicit damping keeps stable (a 7-dof arm's servos make rk4
   unstable above about 1e-5 s); with the file's integrator rbody and MuJoCo run one scheme, equal to round-off
   where no constraint acts, so what remains between them is the constraints' model, rigid against soft.

Contacts between geoms (table.CONTACT, CONTACT1: gap functions from rbody.engine.contacts, Coulomb's circular cone
solved by cone.py) run by either scheme, time-stepping by default (method="moreau": persistent contacts, stacks,
feet and grasps, many candidates touching at once) and event-driven on request (method="rk4": few isolated
contacts, exact impact times and stick/slip/roll transitions). Event-driven, a contact's normal row is held like a
limit's with J' v the gap's second derivative (rbody.engine.contacts.kinematics: the curvature terms); sticking, its
tangent rows are held too and its guard is mu lambda_n - |lambda_t|; sliding, its friction -mu lambda_n s/|s| is a
force column of the held problem (sliding.py) and its guard the slip along its initial direction; the event's
problem is solved with the cones (contact_events.py, cone.py); impacts of contacts are sequential (docs/contacts.md).

A run reports its events (runner.py: trajectory.events and meta["events"]), its constraint forces, errors, held
limits, sticking dofs and the energy dry friction and impacts dissipated (energy + dissipated is conserved where
nothing else loses energy). Bad input (an inconsistent constraint set, no consistent force, a solver that does not
converge within its budget) is a SimulationError naming the time, the constraints and the residual.
"""
