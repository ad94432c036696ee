"""``rblog run --engine ode``: every sample recorded into the contract, and ODE's verdicts held
against what ODE's own state says, computed here without rblog's analyzers:

* impulses: ODE's step is ``v+ = v + dt M^-1 (f_ext + sum_j f_j)`` with the contact joints'
  forces ``f_j`` (their ``dJointFeedback``), and for the rotation ``w+ = w + dt I_w^-1 (tau_ext +
  tau_g + sum_j (p_j - x) x f_j)`` with ``I_w = R I R^T`` at the step's start and ODE's implicit
  gyroscopic torque (Lacoursiere 2006, ode/src/step.cpp and quickstep.cpp): with ``L = I_w w``,
  ``tau_g = (I_w (I_w - dt [L]x)^-1 - 1) L / dt``, which is ``-w x I_w w`` to first order in dt. So
  at every logged step the rows' impulses equal ``m dv - (m g + F) dt`` and ``I_w dw - dt (tau_g
  + tau_ext)`` to round-off: the tolerance is a few hundred ulp of the terms summed.
* the bounce: ODE's ``dContactBounce`` sets the rebound normal velocity to ``-e`` times the
  approach one, then gravity acts for the rest of the step: from the logged velocities either side
  of the impact, ``-v_after / v_before`` is ``e`` within ``2 g dt / v_before``. ODE then moves the
  ball by symplectic Euler, ``v += -g dt; z += v dt``, so from the state (z0, v0) logged after the
  impact the flight's heights are ``z0 + n dt v0 - g dt^2 n (n + 1) / 2``: the highest logged one
  is that at ``n = round(v0 / (g dt) - 1/2)``, which is ``v0 dt / 2`` below the parabola's apex
  ``z0 + v0^2 / 2g`` (1.8 mm at 3.5 m/s here).
* resting depth: ``dCollide`` on a plane and a box geom placed at the logged poses (a world of its
  own) gives the penetration of every sample; the penetration analyzer's worst resting depth is
  the deepest of them.
"""

from __future__ import annotations

import ctypes
import json

import numpy as np
import pytest
from click.testing import CliRunner

from rblog.analyze import check
from rblog.analyze.consistency import inspect
from rblog.engine.scene import load_scene
from rblog.record._common import LOG_FORMAT_VERSION
from rblog.record.reader import load
from rblog.study.engines import EngineUnsupported, run_engine
from tests.conftest import SAMPLES_DIR

ode = pytest.importorskip("odepy", reason="ODE: apt-get install libode8; pip install ode-python")

SAMPLES = sorted(p.stem for p in SAMPLES_DIR.glob("*.toml"))
#: 500 boxes on dWorldQuickStep (the direct LCP of dWorldStep is cubic in the pile's one island):
#: ~1 min per simulated second here, with one Python near callback per candidate pair
HEAVY = ("pile",)
EPS = np.finfo(float).eps


def _run(name, tmp_path, duration=None, options=(), **kw):
    s = load_scene(str(SAMPLES_DIR / f"{name}.toml"))
    rrd, mcap = tmp_path / f"{name}-ode.rrd", tmp_path / f"{name}-ode.mcap"
    summary, traj = run_engine(s, "ode", options=options, duration=duration, rrd=str(rrd),
                               mcap=str(mcap), keep=True, **kw)
    return s, summary, traj, rrd, mcap


def gyroscopic_torque(i_w, w, dt):
    """ODE's implicit gyroscopic torque (N, 3) for world inertias ``i_w`` (N, 3, 3) and angular
    velocities ``w`` (N, 3): ``(I (I - dt [L]x)^-1 - 1) L / dt``, ``L = I w``."""
    lw = np.einsum("nij,nj->ni", i_w, w)
    cross = np.zeros_like(i_w)  # [L]x b = L x b
    cross[:, 0, 1], cross[:, 0, 2], cross[:, 1, 2] = -lw[:, 2], lw[:, 1], -lw[:, 0]
    cross[:, 1, 0], cross[:, 2, 0], cross[:, 2, 1] = lw[:, 2], -lw[:, 1], lw[:, 0]
    tilde = i_w - dt * cross
    m = np.einsum("nij,njk->nik", i_w, np.linalg.inv(tilde)) - np.eye(3)
    return np.einsum("nij,nj->ni", m, lw) / dt


def momentum_residuals(traj):
    """Largest |rows' impulses - momentum change| over the logged steps whose previous step is
    logged too, linear (N s) and angular (N m s), each relative to the step's largest term."""
    m, model = traj.model.body_mass, traj.model
    c = traj.contacts
    g = model.gravity
    steps = {int(s): k for k, s in enumerate(traj.step)}
    worst_lin = worst_ang = 0.0
    inertia = model.body_inertia_diag
    for s in np.unique(c.step):
        if int(s) - 1 not in steps:
            continue
        k1, k0 = steps[int(s)], steps[int(s) - 1]
        dt = traj.t[k1] - traj.t[k0]
        sel = c.step == s
        a, b = c.body_a[sel], c.body_b[sel]
        imp = c.normal_impulse[sel, None] * c.normal[sel] + c.friction_impulse[sel]
        x0 = traj.position[k0]
        lin = np.zeros((model.n_bodies, 3))
        ang = np.zeros((model.n_bodies, 3))
        scale = np.zeros(model.n_bodies)
        for r in range(len(a)):
            lin[a[r]] += imp[r]
            ang[a[r]] += np.cross(c.point[sel][r] - x0[a[r]], imp[r])
            scale[a[r]] += np.linalg.norm(imp[r])
            if b[r] >= 0:
                lin[b[r]] -= imp[r]
                ang[b[r]] -= np.cross(c.point[sel][r] - x0[b[r]], imp[r])
                scale[b[r]] += np.linalg.norm(imp[r])
        touched = scale > 0
        dp = m[:, None] * (traj.velocity[k1] - traj.velocity[k0]) \
            - (m[:, None] * g + model.body_force_world) * dt
        r0 = traj.rotation[k0]
        i_w = np.einsum("nij,nj,nkj->nik", r0, inertia, r0)
        w0, w1 = traj.angular_velocity[k0], traj.angular_velocity[k1]
        dl = np.einsum("nij,nj->ni", i_w, w1 - w0) - dt * (gyroscopic_torque(i_w, w0, dt)
                                                           + model.body_torque_world)
        # round-off scale: the impulses and the momenta either side (the larger of the two)
        lin_scale = scale + m * np.maximum(np.linalg.norm(traj.velocity[k0], axis=1),
                                           np.linalg.norm(traj.velocity[k1], axis=1))
        ang_scale = scale * np.max(model.body_size, axis=1) * 2 + np.maximum(
            np.einsum("nij,nj->n", np.abs(i_w), np.abs(w0)), np.einsum("nij,nj->n", np.abs(i_w), np.abs(w1)))
        if touched.any():
            worst_lin = max(worst_lin, float(np.max(np.linalg.norm(dp - lin, axis=1)[touched]
                                                    / lin_scale[touched])))
            worst_ang = max(worst_ang, float(np.max(np.linalg.norm(dl - ang, axis=1)[touched]
                                                    / ang_scale[touched])))
    return worst_lin, worst_ang


@pytest.mark.parametrize("name", [n for n in SAMPLES if n not in HEAVY])
def test_every_sample_short(name, tmp_path):
    s, summary, traj, rrd, mcap = _run(name, tmp_path, duration=0.3)
    assert summary.steps == round(0.3 / s.sim.dt)
    for got in (load(rrd), load(mcap)):
        assert not got.truncated and got.warnings == []
        assert got.info.engine_settings["engine"] == "ode" and got.info.log_format == LOG_FORMAT_VERSION
        assert got.info.combine_friction == "geometric" and got.info.combine_restitution == "max"
        np.testing.assert_array_equal(got.position, traj.position)
        np.testing.assert_array_equal(got.contacts.normal_impulse, traj.contacts.normal_impulse)
        cons = check(got)[0]
        assert cons.analyzer == "consistency" and cons.passed, cons.reason
    assert inspect(traj) == []
    from rblog_cli.main import main

    res = CliRunner().invoke(main, ["check", "--json", str(mcap)])
    assert res.exit_code in (0, 1), res.output
    doc = json.loads(res.stdout)
    assert doc["logs"][0]["results"][0]["passed"] and doc["logs"][0]["warnings"] == []


@pytest.mark.parametrize("name", ["resting_box", "bouncing_ball", "mixed", "box_stack", "newton_pair"])
@pytest.mark.parametrize("stepper", ["world", "quick"])
def test_impulses_are_the_momentum_change(name, stepper, tmp_path):
    # every step logged, so that each row's step has the state before it
    dur = {"bouncing_ball": 0.5, "mixed": 0.9, "box_stack": 0.3, "newton_pair": 0.7}.get(name, 0.2)
    s, summary, traj, *_ = _run(name, tmp_path, duration=dur, log_every=1,
                                options=[f"stepper={stepper}"])
    assert summary.contacts > 0
    lin, ang = momentum_residuals(traj)
    # round-off of the sums, relative to the step's impulses and momentum: measured (in ulp,
    # world / quick) linear 121 / 123 on the resting box (the contact cancels m g dt within ODE's
    # sum), 20 / 11 in the stack, 4 / 4 in mixed, < 2 on the single impacts; angular < 8
    assert lin < 400 * EPS, lin
    assert ang < 40 * EPS, ang


def test_bounce_from_the_logged_velocities(tmp_path):
    s, _, traj, _, mcap = _run("bouncing_ball", tmp_path, duration=2.0, log_every=1)
    e, g, dt = 0.8, 9.81, s.sim.dt
    z, vz = traj.position[:, 0, 2], traj.velocity[:, 0, 2]
    hits = np.nonzero((vz[:-1] < 0) & (vz[1:] > 0))[0]
    assert len(hits) >= 2
    for k in hits[:2]:
        ratio = -vz[k + 1] / vz[k]
        assert abs(ratio - e) <= 2 * g * dt / abs(vz[k]), ratio
        nxt = hits[hits > k]
        end = nxt[0] if len(nxt) else len(z)
        z0, v0 = z[k + 1], vz[k + 1]
        n = np.arange(max(0, int(v0 / (g * dt) - 0.5) - 1), int(v0 / (g * dt) - 0.5) + 3)
        apex = np.max(z0 + n * dt * v0 - g * dt * dt * n * (n + 1) / 2)
        # round-off of ~350 steps: measured 2e-14 m
        assert abs(z[k + 1:end].max() - apex) <= 1e-12, (z[k + 1:end].max(), apex)
    res = {r.analyzer: r for r in check(load(mcap))}
    assert res["momentum"].passed, res["momentum"].reason  # ODE's e is the scene's


def dcollide_depths(traj, body=0):
    """Box ``body``'s penetration of the ground plane at every logged pose, by dCollide (m)."""
    ode.dInitODE2(0)
    space = ode.dSimpleSpaceCreate(None)
    half = traj.model.body_size[body]
    box = ode.dCreateBox(space, *(2 * half))
    nrm = traj.model.ground_normal
    plane = ode.dCreatePlane(space, *map(float, nrm), float(traj.model.ground_offset))
    buf = (ode.dContactGeom * 8)()
    out = []
    for x, q in zip(traj.position[:, body], traj.quat_wxyz[:, body]):
        ode.dGeomSetPosition(box, *map(float, x))
        ode.dGeomSetQuaternion(box, (ode.dQuaternion)(*map(float, q)))
        k = ode.dCollide(box, plane, 8, buf, ctypes.sizeof(ode.dContactGeom))
        out.append(max((buf[i].depth for i in range(k)), default=0.0))
    ode.dSpaceDestroy(space)
    return np.array(out)


@pytest.mark.parametrize("stepper", ["world", "quick"])
def test_resting_depth_is_dcollides(stepper, tmp_path):
    _, _, traj, _, mcap = _run("resting_box", tmp_path, duration=1.0, log_every=1,
                               options=[f"stepper={stepper}"])
    depth = dcollide_depths(traj)
    res = {r.analyzer: r for r in check(load(mcap))}
    pen = res["penetration"]
    assert pen.passed, pen.reason
    # the analyzer's deepest resting penetration is dCollide's deepest over the same poses (ODE's
    # dWorldStep holds the box within 1.3e-12 m; dWorldQuickStep lets it sink 1.2e-5 m now and
    # then and pulls it back by ERP 0.2 per step)
    assert depth.max() < pen.tolerance
    assert pen.stats["rest_depth_max_m"] == pytest.approx(depth.max(), rel=1e-9, abs=1e-15)
    # and the rows' separations are dCollide's depths at the start of each step (the pose before)
    c = traj.contacts
    assert np.all(c.separation <= 0) and np.all(-c.separation <= depth.max() * (1 + 1e-9))


def test_options_and_what_ode_cannot_take(tmp_path):
    s = load_scene(str(SAMPLES_DIR / "resting_box.toml"))
    summary, _ = run_engine(s, "ode", duration=0.01, options=["stepper=quick", "iterations=50",
                                                               "erp=0.5", "cfm=1e-8"])
    st = summary.settings
    assert st["integrator"] == "dWorldQuickStep" and st["quickstep_iterations"] == 50
    assert st["erp"] == 0.5 and st["cfm"] == 1e-8
    for bad, says in ((["stepper=rk4"], "stepper 'rk4'"), (["iterations=10"], "without stepper=quick"),
                      (["erp=abc"], "erp='abc'"), (["solver=PGS"], "option 'solver'")):
        with pytest.raises(EngineUnsupported, match=says):
            run_engine(s, "ode", duration=0.01, options=bad)
    from rblog_cli.main import main

    res = CliRunner().invoke(main, ["run", str(SAMPLES_DIR / "resting_box.toml"), "--engine", "ode",
                                    "--engine-option", "stepper=rk4", "--no-log"])
    assert res.exit_code == 2 and "cannot represent stepper 'rk4'" in res.output
    assert "Traceback" not in res.output


#: name -> {finding kind (tests/analyze/test_engine_samples.kind): worst value}: what ``rblog
#: check`` finds in ODE's full run of each sample (dWorldStep; the pile dWorldQuickStep), measured
#: 2026-12-01 (ODE 0.16.2, ode-python 0.1.0). Each kind is a real fault of ODE, confirmed below
#: from the logged state itself:
#: * ``flight angular`` / ``flight energy``: ODE's implicit gyroscopic torque (see the module
#:   docstring) does not conserve a tumbling body's L or energy in free flight;
#: * ``cone``: rows outside Coulomb's cone: dContactApprox1 bounds the two friction directions by
#:   mu fn during the LCP solve (a pyramid), and box_stack's dWorldStep at dt 10 ms hits "LCP
#:   internal error" and returns friction with no normal force (relative excess 1);
#: * ``collision angular``: the same gyroscopic step while bodies touch;
#: * ``sink``, ``resting sink``, ``creep``: the stack at dt 10 ms sinks 9 mm where the LCP fails;
#:   ODE's contacts slip 0.2-0.6 mm (friction pyramid, ERP-corrected penetration).
KNOWN = {
    "bouncing_ball": {},
    "box_stack": {"momentum: cone": 1.0, "penetration: sink": 0.00921,
                  "penetration: resting sink": 0.00167},
    "free_fall": {"momentum: flight angular": 0.00195},
    # no creep: the balls roll down the ramp and the boxes slide (33 rolling, 53 sliding
    # stretches, events); the 14 resting stretches creep 1.1e-10 m (2026-12-07)
    "mixed": {"momentum: flight angular": 0.00733, "momentum: cone": 1.0,
              "momentum: collision angular": 0.000642},
    "newton_pair": {},
    # 2026-12-02, geoms in a dSimpleSpace: the 6.33 mm sink read with dHashSpace is gone (that
    # space stopped reporting overlapping pairs: test_engine_shapes), creep 0.320 mm
    "pile": {"momentum: cone": 1.0, "penetration: creep": 0.000223},
    "resting_box": {},
    # measured 2026-12-02 21:20 UTC: friction rows with no normal force. No flight finding: the
    # 0.0039 of |L| read before the audit found capsule contacts from their geoms lay on
    # stretches in which capsules touched between samples; whether ODE's gyroscopic error on the
    # flights left is below the tolerance or they are too short to judge is not measured
    # 2026-12-03, with the hulls and cylinders: the wedge falls onto the slope's lower end at 2.8
    # m/s; ODE's convex-box contact is one point, from the step it overlaps (t = 0.288 s, 0.44 mm
    # deep), and the impact goes 9.84 mm deep (the audit's geom-pair depth; rblog's narrowphase on
    # the logged pose the same; ODE's own rows up to 20.8 mm), pushing it out gains 0.24 J
    # ("contact energy" 0.0847); the nut 5.34 mm into slider1 (ODE's row: 6.08 mm)
    "shapes": {"momentum: cone": 1.0, "penetration: penetration": 0.00984,
               "energy: contact energy": 0.0847},
    "spinning_bodies": {"momentum: flight angular": 0.0486, "energy: flight energy": 0.0647},
    "tumbling_box": {"momentum: flight angular": 0.00365, "energy: flight energy": 0.00734},
}


def _free_flight_l_drift(traj) -> float:
    """Largest relative change of a body's L = R I R^T w over the run, among bodies with no
    contact rows (ballistic the whole run: the samples without contacts)."""
    touched = set(traj.contacts.body_a.tolist()) | set(traj.contacts.body_b.tolist())
    worst = 0.0
    for i in range(traj.model.n_bodies):
        if i in touched:
            continue
        r = traj.rotation[:, i]
        lw = np.einsum("tij,j,tkj,tk->ti", r, traj.model.body_inertia_diag[i], r, traj.angular_velocity[:, i])
        lw = lw - np.outer(traj.t, traj.model.body_torque_world[i])
        worst = max(worst, float(np.max(np.linalg.norm(lw - lw[0], axis=1)) / np.max(np.linalg.norm(lw, axis=1))))
    return worst


@pytest.mark.slow
@pytest.mark.parametrize("name", SAMPLES)
def test_every_sample_full(name, tmp_path):
    """ODE's full runs: ``rblog check`` finds exactly the KNOWN kinds, each within a factor 2 of its
    measured worst value, and each is confirmed from the log (188 s for the nine here)."""
    from tests.analyze.test_engine_samples import kind

    opts = ["stepper=quick"] if name in HEAVY else []
    s, summary, traj, rrd, mcap = _run(name, tmp_path, options=opts)
    got = load(mcap)
    assert not got.truncated
    results = check(got)
    assert results[0].passed
    worst = {}
    for r in results:
        for f in r.findings:
            k = f"{r.analyzer}: {kind(r.analyzer, f.message)}"
            worst[k] = max(worst.get(k, 0.0), abs(f.value))
    want = KNOWN[name]
    assert set(worst) == set(want), worst
    for k, v in want.items():
        assert v / 2 <= worst[k] <= 2 * v, (k, worst[k], v)
    mom = next(r for r in results if r.analyzer == "momentum")
    if "momentum: flight angular" in want and name not in ("mixed", "shapes"):  # bodies that touch
        # nothing the whole run (in mixed and shapes every body lands)
        assert _free_flight_l_drift(got) > mom.tolerance
    if "momentum: cone" in want:
        c = got.contacts
        mu = np.sqrt(np.outer(got.model.body_friction, np.append(got.model.body_friction, got.model.ground_friction)))
        fric = np.linalg.norm(c.friction_impulse, axis=1)
        lim = np.array([mu[a, b] for a, b in zip(c.body_a, np.where(c.body_b < 0, got.model.n_bodies, c.body_b))])
        assert np.any(fric > lim * c.normal_impulse * (1 + 1e-3) + 1e-12)


def test_cli_bench_and_run_print_ode(tmp_path):
    """``rblog bench --quick --peer ode`` prints ODE's rows; ``rblog run --engine ode --check``
    audits the run as it goes."""
    from rblog_cli.main import main

    res = CliRunner().invoke(main, ["bench", "--quick", "--peer", "ode", "--problem", "bouncing-ball",
                                    "--integrator", "rk4", "--dt", "0.01", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    rows = [ln for ln in res.output.splitlines() if ln.startswith("ode/")]
    assert {ln.split()[0] for ln in rows} == {"ode/dWorldStep", "ode/dWorldQuickStep"}, res.output
    doc = json.loads((tmp_path / "bench.json").read_text())
    assert doc["settings"]["peers"]["ode"].startswith("ode-python")
    res = CliRunner().invoke(main, ["run", str(SAMPLES_DIR / "bouncing_ball.toml"), "--engine", "ode",
                                    "--check", "--no-log", "--duration", "1.5"])
    assert res.exit_code == 0, res.output
    assert "pass momentum" in res.output and "integrator dWorldStep" in res.output
