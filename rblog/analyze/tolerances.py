"""Default tolerances of the `rblog check` analyzers, each named with its unit.

Every analyzer takes overrides keyed ``"<analyzer>.<name>"`` where ``<name>`` is the lower-case
constant name without the analyzer prefix: ``DRIFT_ORTHO_ERROR`` is ``drift.ortho_error``,
``PENETRATION_DEPTH_M`` is ``penetration.depth_m``. Suffixes give the unit: ``_m`` metres,
``_mps`` m/s, ``_s`` seconds, ``_rel`` / ``_frac`` dimensionless ratios, ``_samples`` a count.
Ratios without a suffix (``ortho_error``) are dimensionless too.

How they were chosen (numbers for the engine's defaults, dt = 1e-3 .. 1e-2 s, logged at 100 Hz):

* Round-off of a correct float64 run is ~1e-16 per operation and grows like sqrt(steps): after
  1e8 steps it is ~1e-12. Everything meant to hold "exactly" (rigidity, momentum in a collision)
  is given 1e-6, six orders above round-off and many below any real fault (the lecture notes'
  scheme without orthonormalization stretches a body by h*|w|^2 ~ 4e-3 per second at h = 1e-3,
  w = 2 rad/s; the planted momentum faults are ~1e-2).
* Energy is not conserved exactly by a correct integrator: a first-order (symplectic Euler)
  gravity step keeps a shadow energy that differs from E by m g.v dt/2, so the energy analyzer
  allows twice that, m |g| |v| dt per sample, on top of its relative tolerance (dt =
  ``RunInfo.dt``), and a
  second-order rotation step has a bounded relative error ~(|w| dt)^2 ~ 1e-4 for 10 rad/s at
  dt = 1e-3. The notes' `seed` scheme gains ~1.6e-3 of the energy in 5 s on the tumbling box at
  dt = 1e-3 (7e-3 after 20 s), so 1e-3 separates the two.
* Contact: the contact issue's targets are <= 0.1 mm resting penetration (0.5 mm in a 500-box
  pile, 1 mm peak at a 4.4 m/s bounce) and ~1e-6 m/s at rest; the defaults here flag what a
  viewer would show (a 1 mm sink, a 2 mm/s shimmer, a 1 mm slide) rather than the engine targets,
  so that logs of other engines are judged by what is visibly wrong. Tighten them with overrides
  to test an engine against its own targets.
"""

from __future__ import annotations

#: name endings -> unit, longest first (an option's name carries its unit; "1" where none does)
_UNIT_SUFFIXES = (("_j_per_kg", "J/kg"), ("_samples", "samples"), ("_mps", "m/s"),
                  ("_ns", "N s"), ("_rad", "rad"), ("_m", "m"), ("_s", "s"))


def unit_of(name: str) -> str:
    """The unit an option's name ends in: ``depth_m`` is in m, ``cone_floor_ns`` in N s."""
    return next((u for suffix, u in _UNIT_SUFFIXES if name.endswith(suffix)), "1")


def options(analyzer: str, *names: str, **shared: float) -> dict[str, float]:
    """An analyzer's options (name -> default): each of ``names`` is this module's constant
    ``<ANALYZER>_<NAME>`` (``options("drift", "ortho_error")`` reads DRIFT_ORTHO_ERROR);
    ``shared`` names defaults kept under another constant (``contact_distance_m=
    CONTACT_DISTANCE_M``)."""
    g = globals()
    return {**{n: g[f"{analyzer.upper()}_{n.upper()}"] for n in names}, **shared}


# --- shared geometry --------------------------------------------------------------------------
#: Two surfaces closer than this (m) are "in contact" (resting detection, contact intervals).
#: Engines keep resting contacts within ~0.1 mm (speculative margin) of touching; 1 mm also
#: covers the separating-axis lower bound used for separated boxes.
CONTACT_DISTANCE_M = 1e-3

#: Thickness of a box's touching feature (m): the points of a box within this distance of its
#: extreme along a contact normal make the face, edge or corner that touches (a box axis is
#: "free", spanned by the feature, when 2 h_j |n.A_j| <= this). The witness point of a contact
#: (rblog.analyze.geometry) is the centre of the patch where the two touching features overlap,
#: so a box resting on its face has its witness at the face's centre even when tilted by round-off
#: or by the engine's settling. 0.1 mm: engines hold resting contacts within ~0.05 mm of touching
#: (rblog's allowed penetration is 5e-5 m; the 500-box pile's resting separations are about
#: -50 um), so a face whose corners differ in height by less than this rests on all of them; a
#: 0.1 m box face tilted by up to 1 mrad still counts as a face, one tilted by 0.05 rad (5 mm
#: across) rests on its lowest edge. Only where the witness lies depends on it, not a separation.
WITNESS_BAND_M = 1e-4

#: GJK stops when the distance between two convex cores is known to within this (m; the gap
#: between its upper bound |v| and lower bound v.w/|v|, csrc/audit/convex.cpp). For polytope
#: cores (point, segment, box, mesh) GJK ends on the exact closest feature before reaching it;
#: for cylinders and ellipsoids it is the error. 1e-10 m: five orders below the 1e-5 m scale of
#: a contact finding, reached in ~20-60 iterations on curved pairs.
GJK_TOL_M = 1e-10
#: EPA stops when the penetration depth is known to within this (m; the gain of the support along
#: the nearest face's normal): exact faces for polytopes, the error for curved cores.
EPA_TOL_M = 1e-10
#: Iteration cap of GJK and of EPA each (a pair that hits it is reported "not converged").
#: EPA on a curved core converges slowest where the nearest boundary point is on a flat part of
#: it (the depth error of a face of spacing s is s^2 / 2 R_curvature): of 10,000 deep
#: sphere-ellipsoid poses 25 needed more than 256 iterations for EPA_TOL_M; polytope pairs end in
#: <= 30.
CONVEX_MAX_ITER = 1000

#: Most findings kept per analyzer (the worst first); the count of all is in stats.
MAX_FINDINGS = 200
#: Most events (impacts, resting intervals, rolling and sliding stretches: a fifth kept for
#: these) listed per analyzer; all are counted in stats.
MAX_EVENTS = 500

# --- joints ----------------------------------------------------------------------------------
#: Round-off allowed in a joint's anchor separation and axis angle, in units of the log's float
#: precision (eps of the position dtype) times the size of the numbers in the transform (m; 1 for
#: angles): a pose is a product of a few rotations and sums per level of a kinematic chain, each
#: good to a few ulps, and the reader rebuilds R from the logged quaternion (~4 ulps). 64 ulps:
#: a MuJoCo chain of 4 hinges measures <= 0.5 ulp in its anchors and 5 ulps in its axes
#: (tests/analyze/test_joints.py); pybullet's maximal-coordinates chain there is ~6e12 ulps
#: (2.6 mm) apart. The step term of the tolerance (rblog/analyze/joints.py) is derived, not set
#: here.
JOINTS_ROUNDOFF_ULPS = 64.0

# --- drift (rigidity) -------------------------------------------------------------------------
#: ||R^T R - I||_F, recomputed from the logged rotation (dimensionless).
DRIFT_ORTHO_ERROR = 1e-6
#: |det R - 1| (dimensionless; a volume change).
DRIFT_DET_ERROR = 1e-6
#: ||q| - 1| of the logged quaternion (dimensionless).
DRIFT_QUAT_NORM_ERROR = 1e-6
#: Relative change of the distance between body-fixed points (box corners, +-radius along the
#: axes) mapped by the logged rotation, vs their rigid distance: 1e-6 = 1 um per metre.
DRIFT_DISTANCE_REL = 1e-6

# --- momentum in collisions -------------------------------------------------------------------
#: A body's momentum change between two samples that differs from (m g + F) dt by more than this
#: fraction of its momentum scale m(|v| + |a| dt) marks a contact (or a fault); only a detector.
MOMENTUM_JUMP_REL = 1e-9
#: A logged contact with static geometry whose normal is more than this angle (rad) off the
#: ground's is with another static feature than the ground (a tilted plane: dm_control
#: manipulator's wall2 at 45 deg), so the body touches two static features and its impulse is not
#: judged against the ground's friction cone alone. 1 deg: a contact on the ground has the
#: plane's normal exactly (MuJoCo, pybullet, rblog).
STATIC_NORMAL_OTHER_RAD = 0.017453292519943295  # 1 deg
#: |sum of linear impulses| of a group of colliding bodies (no static geometry involved), relative
#: to sum_i m_i |v_i| of the group.
MOMENTUM_LINEAR_REL = 1e-6
#: |change of the group's angular momentum about its centre of mass| minus applied torques,
#: relative to sum_i (|L_i| + |x_i - c| |P_i|). Uniform gravity exerts no torque about the centre
#: of mass, in continuous and in discrete (symplectic Euler) time, so this is exact; it is the
#: angular momentum about the origin with the gravity torque c x M g removed.
MOMENTUM_ANGULAR_REL = 1e-6
#: Floors of those scales, per body: its mass times this speed (m/s), its largest principal
#: moment times this spin (rad/s) (the jump detector's floor, rblog.analyze.base). Bodies at rest
#: in zero gravity have no momentum to compare a residue with: MuJoCo's 1e-32 kg m/s round-off
#: over a 1e-33 scale once read as a relative change of 1.86. Lone bodies (nothing in reach) are
#: judged by the same LINEAR_REL / ANGULAR_REL over each free flight, once per flight.
MOMENTUM_SPEED_FLOOR_MPS = 1e-9
MOMENTUM_SPIN_FLOOR_RADPS = 1e-9
#: Coulomb cone: |J_t| <= mu J_n + cone_rel |J| (impulse J over a sample interval, inferred from
#: the momentum change, or as logged). Sums of in-cone impulses on one normal stay in the cone.
MOMENTUM_CONE_REL = 1e-3
#: Approach speed (m/s, normal, at the contact) above which a contact counts as an impact.
MOMENTUM_IMPACT_SPEED_MPS = 0.1
#: |e_effective - e_configured| allowed for a sphere's impact event, as a fraction of the
#: configured e (dimensionless): 2% of e (0.016 at e = 0.8, so MuJoCo's 0.82 for a configured 0.8
#: is caught), on top of what the samples leave unknown: the moment of the impulse, anywhere from
#: the touch to the separation and within the integrator steps they fall in, which gives a range
#: of restitutions (rblog.analyze.events, Events.e_lo .. e_hi; one step at a 1 m drop: 0.033 at
#: dt = 10 ms, 0.0033 at 1 ms); only the part of the range between e_effective and the configured
#: e is added. e_effective is the whole event's -v_n(separation) / v_n(touch), so an impact a soft
#: engine spreads over many steps is judged once.
MOMENTUM_RESTITUTION_REL = 0.02
#: An event is judged as an impact (restitution, lost bounce) only while the free acceleration
#: changes the normal velocity during it by less than this fraction of the approach speed,
#: |a_n| D < frac |v_n-| (dimensionless): a soft engine's bounce lasts a few ms (MuJoCo here:
#: 3 ms, 0.7% of a 4.4 m/s approach); a ball that lands on a ramp and rolls along it for 0.24 s
#: is in a rolling contact, whose "restitution" means nothing.
MOMENTUM_IMPACT_GRAVITY_FRAC = 0.25
#: Below this approach speed (m/s) a lower effective restitution is not flagged: engines use no
#: restitution for slow impacts (Box2D's threshold is 1 m/s) so that bodies come to rest.
MOMENTUM_RESTITUTION_MIN_SPEED_MPS = 1.0
#: Kinetic + potential energy may grow across an impact event (restitution <= 1) by at most this
#: fraction of the colliding bodies' kinetic energy before the event, besides the dt and position
#: allowances.
MOMENTUM_ENERGY_REL = 1e-3
#: An impact event between bodies whose configured (combined) restitution is 1 must keep the
#: kinetic energy: |E_after - E_before| <= this fraction of the kinetic energy before (1), besides
#: the dt allowance. 0.5%: a head-on pair at e = 0.9967 (Bullet at 3 m/s) loses 0.64% and is
#: caught; rblog's impulse solver keeps it to round-off, MuJoCo at dampratio 1e-4 to ~0.03%.
MOMENTUM_ELASTIC_ENERGY_REL = 5e-3
#: Absolute floor of a friction-cone excess (N s): a contact impulse outside the cone by less than
#: this is not reported. It is tied to the impulse resolution of a log: impulses are inferred from
#: momentum differences (or logged as force x dt), and a log at 100 Hz resolves ~1e-4 N of force
#: (1e-6 N s per sample) at best once float32 viewers or a solver's tolerance are involved; the
#: cone test in float64 flagged sub-micro-newton-second residues of converged solvers.
#: A CONE_RESOLUTION_ULPS x float64 epsilon x the body's momentum scale m (|v| + |a| dt) is added
#: (the round-off of the momentum difference itself).
MOMENTUM_CONE_FLOOR_NS = 1e-6
MOMENTUM_CONE_RESOLUTION_ULPS = 1e3
#: A bounce is lost when an impact faster than RESTITUTION_MIN_SPEED_MPS with configured e > 0
#: ends with the body at rest on its partner (no separation) although it should leave at
#: e |v_n| >= this speed (m/s).
MOMENTUM_LOST_BOUNCE_MPS = 0.5

# --- penetration during resting contact -------------------------------------------------------
#: Max resting depth (m), capped by DEPTH_FRAC of the body's smallest half-extent (radius): 1 mm is
#: about one pixel at 1 m across a 1000-px view; a 1 cm marble gets 0.25 mm.
PENETRATION_DEPTH_M = 1e-3
PENETRATION_DEPTH_FRAC = 0.05
#: Max depth at any sample, impacts included (m), capped by TRANSIENT_FRAC of the smallest
#: half-extent: a momentary 5 mm sink at a fast impact is tolerable, 25% of the body is not.
PENETRATION_TRANSIENT_DEPTH_M = 5e-3
PENETRATION_TRANSIENT_FRAC = 0.25
#: Resting: in contact with every point's speed relative to the partner (the contact point's plus
#: the relative angular speed times twice the bounding radius) below this (m/s), for at least
#: REST_MIN_SAMPLES consecutive samples. A contact that moves with a normal speed at most this
#: rolls (its slip at most this: the contact point at rest) or slides (rule "rolling_sliding").
PENETRATION_REST_SPEED_MPS = 0.05
PENETRATION_REST_MIN_SAMPLES = 3
#: Jitter is measured after the body has rested this long (s): a body sliding to a stop from
#: REST_SPEED under friction mu >= 0.05 needs < 0.1 s. Creep counts the whole stay but the
#: settling slide within this time: the slide before the body first slows to its least, and what
#: it slides faster than its steady slip over the next SETTLE_S (rblog.analyze.penetration).
PENETRATION_SETTLE_S = 0.1
#: Max jitter while settled (m/s): the alternating part of the contact-point velocity between
#: samples (see rblog.analyze.penetration). 2 mm/s is 20 um per frame at 100 Hz, below what shows;
#: it also stays above the kink of a body put to sleep from the engine's sleep speed (5 mm/s ->
#: 0 gives 1.25 mm/s). A good engine is at ~1e-6 m/s.
PENETRATION_JITTER_MPS = 2e-3
#: Jitter must persist: the alternating amplitude is the smallest of this many consecutive
#: samples (samples). A step change of velocity (a kick) makes two alternating second
#: differences, a one-sample spike three; an oscillation that lasts longer is jitter.
PENETRATION_JITTER_PERSIST_SAMPLES = 4
#: Max net slide at the contact while settled (m), over the whole resting interval less its
#: settling slide (SETTLE_S), from the poses (rblog.analyze.penetration); only samples slower than
#: CREEP_SPEED_MPS count, so that a body
#: that slides off (a ramp steeper than its friction allows) is not creep, and only sample
#: intervals over which the contact slid slower than it on average (a kick between two slow
#: samples is a slide). 0.1 mm: a box that creeps a fraction of a millimetre over
#: seconds is wrong (static friction holds it exactly); rblog's own impulse solver keeps a
#: resting box to ~1e-9 m, pybullet's resting cube slips 0.08 mm in 2 s.
PENETRATION_CREEP_M = 1e-4
PENETRATION_CREEP_SPEED_MPS = 1e-2
#: Sliding is not resting: a contact whose logged points are at their Coulomb limit, ``|f| >= (1 -
#: SLIDE_CONE_FRAC) mu J_n``, all but at most one (a rigid contact that slips slips at every point
#: but the one it may pivot about), over the logged rows of the pair at the sample's step (sliding,
#: or twisting about the normal: a box in the 500-box pile turning at 0.05 rad/s on its support has
#: all 4 points at the limit, each in its own direction, their vector sum at 0.83 of mu sum J_n; a
#: box pivoting on an edge has 1 of 2), or whose tangential load (the body's other contact impulses
#: plus (m g + F) dt) reaches that limit, is sliding (dimensionless fraction of the limit mu J_n).
#: Static friction holds strictly inside the cone; on its boundary the contact slips, which the
#: notes' resting-contact model does not cover, so its slip is not creep. Normal impulses below
#: SLIDE_FLOOR_NS (= MOMENTUM_CONE_FLOOR_NS, the impulse resolution of a log) carry no friction to
#: judge; a support none of whose rows at the step carries more is unloaded (limit mu x 0) and
#: slides too (rblog's pile at seed 2: box 177 chattering on box 130, loaded between samples).
#: Without logged contact rows only a body touching nothing but its support can be judged (from
#: its inferred impulse). 1%: every engine's points at the limit are there to round-off
#: (logged |f| / (mu J_n) within 1e-9 of 1: 62,016 of rblog's 438,425 pile rows, 8,769 of MuJoCo's
#: 42,112, 25,824 of pybullet's 60,737 in 1 s of the pile), and few lie just inside (0.99 .. 1 -
#: 1e-9: rblog 4.4%, MuJoCo 0.46%, pybullet 0.65% of rows), so the choice within 1e-9 .. 0.1 moves
#: few samples.
PENETRATION_SLIDE_CONE_FRAC = 1e-2

# --- energy -----------------------------------------------------------------------------------
#: Drift of a free body's energy over a contact-free stretch, relative to the stretch's energy
#: scale max(max kinetic energy, range of potential energy) (the potential's zero is arbitrary, so
#: |E0| is not a scale), on top of m |a| dt (|v_t| + |v_0|)/2 for first-order gravity steps.
ENERGY_DRIFT_REL = 1e-3
#: Gain of the colliding bodies' energy across a contact interval, relative to their kinetic
#: energy, on top of the dt allowance and POSITION_CORRECTION_M below.
ENERGY_CONTACT_GAIN_REL = 1e-3
#: An engine's position correction may lift a body out of penetration (m): m |g| times this is
#: allowed as potential-energy gain per contact interval (the resting depth tolerance).
ENERGY_POSITION_CORRECTION_M = 1e-3
#: The gravity-step allowance is this many times m |a| dt (|v(t)| + |v(0)|) / 2. For symplectic
#: Euler the energy error over a free arc is exactly m g.dv dt / 2 (a shadow energy), which this
#: bound reaches at every apex-symmetric pair of samples; twice it leaves room for integrators
#: that split the step otherwise (explicit Euler has the same size, opposite sign) and round-off.
ENERGY_DT_FACTOR = 2.0
#: Energy scales below this (J per kg of the body) count as zero motion: drift is then judged
#: against this floor.
ENERGY_FLOOR_J_PER_KG = 1e-9

# --- tunneling --------------------------------------------------------------------------------
#: How far a body's centre may cross the ground plane or enter a static box between two samples
#: (m). A correct run never puts a centre inside solid geometry.
TUNNELING_CROSSING_M = 0.0
#: Two bodies tunnel through each other when the straight path between samples brings their
#: centres closer than this fraction of the sum of their inner radii (sphere radius, smallest box
#: half-extent) while they are apart at both samples.
TUNNELING_PASS_FRAC = 0.5
#: Geom pairs (rblog.analyze.tunneling): the pose of each geom is interpolated between two
#: samples at sub-steps no farther apart than this fraction of the pair's depth threshold in the
#: displacement of any of their points, so a pass whose deepest point exceeds the threshold by
#: this half-fraction is never stepped over (signed distance is 1-Lipschitz in displacement).
TUNNELING_SUBSTEP_FRAC = 0.5
#: At most this many sub-steps per pair and interval (a pair that moves farther than
#: TUNNELING_SUBSTEP_FRAC x its threshold x this between two samples is sampled more coarsely; the
#: stats count them as ``geom_rows_capped``).
TUNNELING_MAX_SUBSTEPS = 64

# --- consistency (contract checks on read; rblog.analyze.consistency) --------------------------
#: ||R(q/|q|) - R||_F beyond (this + 2 ||R^T R - I||_F) means quat_wxyz and rotation disagree
#: (dimensionless). A writer that derives one from the other agrees to ~1e-15; a transposed matrix
#: or a quaternion in xyzw order differs by O(1) once the body has turned.
CONSISTENCY_QUAT_MATRIX = 1e-6
#: |p - m v| relative to |p| (+ 1e-12 kg m/s): p and v are one quantity (dimensionless).
CONSISTENCY_MOMENTUM_REL = 1e-9
#: |w - R diag(1/I_body) R^T L| relative to |w| + |L| / I_min (dimensionless). rblog derives w
#: from L exactly (~1e-16); a writer that logs body-frame w and world L differs by O(1).
CONSISTENCY_ANGULAR_MOMENTUM_REL = 1e-6
#: median over a body's sample intervals of |rotvec(R(k+1) R(k)^T)/dt - mean w| relative to |w|
#: (dimensionless): the logged world angular velocity must turn the logged orientation. The
#: midpoint rule errs by ~(|w| dt)^2 (1e-4 at 1 rad per sample); contacts make a few intervals
#: wrong, the median ignores them; a body-frame w, a transposed matrix or a quaternion in xyzw
#: order give O(1).
CONSISTENCY_KINEMATIC_REL = 0.1
#: intervals turning by less than this (rad) or moving less than this times 1 m are not used by
#: the kinematic checks (nothing to compare against round-off).
CONSISTENCY_MIN_ANGLE_RAD = 1e-4
#: intervals where the logged rate changes by more than this fraction of itself held an impulse
#: (a contact) and are left out of the kinematic checks (dimensionless; a pile of 500 boxes
#: otherwise shows a median mismatch of 0.27 from its collisions alone).
CONSISTENCY_SMOOTH_FRAC = 0.25
#: position correction an engine may apply without a velocity (split impulse, projection of
#: penetrating contacts), per sample interval (a box in rblog's 500-box pile turns ~1e-3 rad per
#: 10 ms interval by projection alone while nearly at rest; the faults above give O(|w| dt)).
#: Turn: 1e-3 rad is allowed on top of the relative mismatch, rel = max(d dt - corr, 0) /
#: (|w| dt), and an interval turning less than it is not used (csrc/audit/consistency.cpp,
#: kinematic_rel; samples/pile.toml's box125 at seed 6 with exact_contact_motion, rocked back by
#: the split-impulse relax each step, is 2e-4 rad per interval off its logged w of 0.02 rad/s:
#: tests/analyze/test_consistency.py). Shift: 1e-3 m joins the scale instead, d / (|v| + acc dt
#: + corr / dt) (linear_rel).
CONSISTENCY_CORRECTION = 1e-3
#: a body needs this many usable intervals before its kinematic median is judged (count).
CONSISTENCY_MIN_INTERVALS_SAMPLES = 5

# --- diff (two logs of one scene; rblog.analyze.diff) -------------------------------------------
#: a body's centre-of-mass positions in the two logs may differ by this much (m): 1 cm, what a
#: viewer shows as "the same place" for the samples' 0.1-1 m bodies.
DIFF_POSITION_M = 1e-2
#: and its orientations by this angle (rad, ~5.7 degrees).
DIFF_ANGLE_RAD = 0.1
#: divergences below this (m) are round-off and left out of the growth-rate fit.
DIFF_FLOOR_M = 1e-9
#: orientation differences below this (rad) likewise.
DIFF_FLOOR_RAD = 1e-9
