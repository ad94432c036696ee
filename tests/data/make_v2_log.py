# Writes tests/data/v2_log.mcap and v2_log.rrd: a log of contract version 2, as rblog wrote it
# before version 3 (run with the v2 code: `python make_v2_log.py` in a checkout of main at 258af21).
# tests/contract/test_v3.py reads them back with the v3 reader.
import numpy as np, rblog
from rblog.record import Recorder
# a v2 log as rblog main writes it: a sphere and a box on the ground, a static box, 20 samples
m = rblog.body_table(name=["ball", "crate"], shape=["sphere", "box"], size=[[0.1, 0, 0], [0.2, 0.1, 0.05]],
                     mass=[1.0, 2.0], restitution=[0.5, 0.3], friction=[0.4, 0.6], group=[0, 2], ground=True,
                     ground_friction=0.7, ground_restitution=0.2,
                     static_box_position=[[1.0, 0.0, 0.5]], static_box_half_extents=[[0.5, 0.5, 0.5]],
                     static_box_quat_wxyz=[[np.cos(0.1), 0, 0, np.sin(0.1)]])
T = 20
t = np.arange(T) * 0.01
x = np.zeros((T, 2, 3)); x[:, 0, 2] = 1 - 4.905 * t**2; x[:, 1] = [0.5, 0, 0.05]
v = np.zeros((T, 2, 3)); v[:, 0, 2] = -9.81 * t
q = np.tile([1.0, 0, 0, 0], (T, 2, 1))
w = np.zeros((T, 2, 3)); w[:, 1, 2] = 0.3
for path in ("v2_log.mcap", "v2_log.rrd"):
    kw = {"mcap": path} if path.endswith("mcap") else {"rrd": path}
    with Recorder(m, dt=0.01, writer="rblog main (v2)", **kw) as rec:
        rec.write(t=t, position=x, quat_wxyz=q, velocity=v, angular_velocity=w,
                  contacts=dict(step=[5], body_a=[1], body_b=[-1], point=[[0.5, 0, 0]], normal=[[0, 0, 1]],
                                separation=[-1e-4], normal_impulse=[0.196]))
print(rblog.load("v2_log.mcap").info.log_format)
