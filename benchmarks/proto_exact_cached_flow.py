"""PROTOTYPE, not wired into the engine (issue 17, item "exact at <= 300 ns per body-step"):
the exact free flow with its per-body constants computed once per body (sort and case, m, lam,
the amplitudes, sn/cn/dn of the constant phase step lam h, the half-period R_J: all functions of
L_body's invariants and h) and the start's R_J taken from the previous step's end, so a step
evaluates one R_J instead of two and no sncndn. Timed side by side with the kernel
(advance_free, METHOD_EXACT, one thread) on 10,000 random bodies x 100 steps under gravity, and
checked against it (max |q difference| after 100 steps).

    python benchmarks/proto_exact_cached_flow.py

Why it is not wired: carrying values from step to step makes a run depend on where the run loop
splits it into compiled calls (sized by wall time) unless the cache lives in the run's state
between calls, and it must be dropped whenever L changes (a torque kick, a contact). The
prototype also skips the kernel's non-finite and turn-bound checks and writes no samples."""
import math
import time

import numpy as np
from numba import njit

from rblog.engine.exact import sncndn, carlson_rf_rj, carlson_rj_pair, _euler_quat, _qmul, free_flow_body
from rblog.engine.free import advance_free
from rblog.engine.integrators import METHOD_CODES, ORTHO_CODES
from rblog.engine.rotation import quat_to_matrix_np


@njit(cache=False)
def consts(b0, b1, b2, k0, k1, k2, h):
    ia, ib, ic = 0, 1, 2
    ka, kb, kc = k0, k1, k2
    la, lb, lc = b0, b1, b2
    if ka < kb:
        ia, ib, ka, kb, la, lb = ib, ia, kb, ka, lb, la
    if kb < kc:
        ib, ic, kb, kc, lb, lc = ic, ib, kc, kb, lc, lb
    if ka < kb:
        ia, ib, ka, kb, la, lb = ib, ia, kb, ka, lb, la
    par = 1.0 if (ib - ia) * (ic - ia) * (ic - ib) > 0 else -1.0
    d_sep = la * la * (kb - ka) + lc * lc * (kb - kc)
    if d_sep >= 0.0:
        i1, i2, i3 = ia, ib, ic
        kk1, kk2, kk3 = ka, kb, kc
        l1, l2, l3 = la, lb, lc * par
        sgn3 = par
        case_sign = 1.0
    else:
        i1, i2, i3 = ic, ib, ia
        kk1, kk2, kk3 = kc, kb, ka
        l1, l2, l3 = lc, lb, -la * par
        sgn3 = -par
        case_sign = -1.0
    d_t = d_sep
    ell = math.sqrt(l1 * l1 + l2 * l2 + l3 * l3)
    d13 = kk1 - kk3
    d23 = kk2 - kk3
    d12 = kk1 - kk2
    p_t = l1 * l1 * d13 + l2 * l2 * d23
    q_t = l2 * l2 * d12 + l3 * l3 * d13
    m = d12 * p_t / (d23 * q_t)
    m1 = max(d13 * d_t / (d23 * q_t), 0.0)
    m = min(m, 1.0)
    lam = math.sqrt(d23 * q_t)
    amp1 = math.sqrt(p_t / d13)
    amp2 = math.sqrt(p_t / d23)
    amp3 = math.sqrt(q_t / d13)
    nn = d12 / d23
    tau = lam * h
    snr, cnr, dnr, j, big_k = sncndn(tau, m, m1)
    gc = snr * snr / (1.0 + cnr) if cnr > 0.0 else 1.0 - cnr
    gd = m * snr * snr / (1.0 + dnr)
    _, rj_c = carlson_rf_rj(0.0, m1, 1.0, 1.0 + nn)
    s = 1.0 if l3 >= 0.0 else -1.0
    fc = np.array([kk1, ell, d13, m, m1, lam, amp1, amp2, amp3, nn, snr, cnr, dnr, gc, gd, rj_c,
                   sgn3, case_sign * s, s, h, float(j), 1.0 if big_k == math.inf else 0.0])
    ic_ = np.array([i1, i2, i3])
    return fc, ic_, l1, l2, l3


@njit(cache=False)
def step_cached(fc, ic_, l1, l2, l3, rj0):
    kk1, ell, d13, m, m1, lam, amp1, amp2, amp3, nn = fc[0], fc[1], fc[2], fc[3], fc[4], fc[5], fc[6], fc[7], fc[8], fc[9]
    snr, cnr, dnr, gc, gd, rj_c, sgn3, sigma, s, h = fc[10], fc[11], fc[12], fc[13], fc[14], fc[15], fc[16], fc[17], fc[18], fc[19]
    j = int(fc[20])
    sep = fc[21] > 0.0
    cn0 = l1 / amp1
    sn0 = sigma * l2 / amp2
    dn0 = abs(l3) / amp3
    mu_ = m * sn0 * sn0 * snr * snr
    den = 1.0 / (1.0 - mu_)
    gam = gc + gd - gc * gd
    sn1 = sn0 + (snr * cn0 * dn0 - sn0 * gam + sn0 * mu_) * den
    cn1 = cn0 + (-cn0 * gc - sn0 * snr * dn0 * dnr + cn0 * mu_) * den
    dn1 = math.sqrt(cn1 * cn1 + m1 * sn1 * sn1)
    sg0 = 1.0 if cn0 >= 0.0 else -1.0
    s_red0 = sg0 * sn0
    if sg0 * cn1 >= 0.0:
        e = 0
        s_red1 = sg0 * sn1
        if s_red1 - s_red0 < -1.0:
            e = 2
    else:
        e = 1
        s_red1 = -sg0 * sn1
        if s_red1 - s_red0 > 1.0:
            e = -1
    dg = 0.0
    rj1 = 0.0
    if nn != 0.0:
        s20, s21 = s_red0 * s_red0, s_red1 * s_red1
        if rj0 < 0.0:
            rj0, rj1 = carlson_rj_pair(cn0 * cn0, dn0 * dn0, 1.0 + nn * s20, cn1 * cn1, dn1 * dn1, 1.0 + nn * s21)
        else:
            _, rj1 = carlson_rf_rj(cn1 * cn1, dn1 * dn1, 1.0, 1.0 + nn * s21)
        dg = (s_red1 * s21 * rj1 - s_red0 * s20 * rj0) / 3.0
    if sep:
        e = 0
    halfs = j + e
    if halfs != 0 and nn != 0.0:
        dg += 2.0 * halfs * rj_c / 3.0
    dphi = ell * kk1 * h - ell * d13 * nn / lam * dg
    sj = -1.0 if (j & 1) else 1.0
    n1_ = amp1 * cn1 * sj
    n2_ = sigma * amp2 * sn1 * sj
    n3_ = s * amp3 * dn1
    aw, ax, ay, az = _euler_quat(l1, l2, l3, ell)
    bw, bx, by, bz = _euler_quat(n1_, n2_, n3_, ell)
    ch, sh = math.cos(0.5 * dphi), math.sin(0.5 * dphi)
    tw, tx, ty, tz = _qmul(aw, -ax, -ay, -az, ch, 0.0, 0.0, sh)
    cw, cx, cy, cz = _qmul(tw, tx, ty, tz, bw, bx, by, bz)
    c = np.zeros(3)
    c[ic_[0]] = cx
    c[ic_[1]] = cy
    c[ic_[2]] = cz * sgn3
    nc = 1.0 / math.sqrt(cw * cw + c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
    if cw < 0.0:
        nc = -nc
    return cw * nc, c[0] * nc, c[1] * nc, c[2] * nc, n1_, n2_, n3_, rj1


@njit(cache=False)
def lb_of(q, L):
    w, x, y, z = q[0], q[1], q[2], q[3]
    r00 = w * w + x * x - y * y - z * z; r01 = 2.0 * (x * y - w * z); r02 = 2.0 * (x * z + w * y)
    r10 = 2.0 * (x * y + w * z); r11 = w * w - x * x + y * y - z * z; r12 = 2.0 * (y * z - w * x)
    r20 = 2.0 * (x * z - w * y); r21 = 2.0 * (y * z + w * x); r22 = w * w - x * x - y * y + z * z
    return (r00 * L[0] + r10 * L[1] + r20 * L[2], r01 * L[0] + r11 * L[1] + r21 * L[2],
            r02 * L[0] + r12 * L[1] + r22 * L[2])


@njit(cache=False)
def store(q, R, i, w, x, y, z):
    q[i, 0], q[i, 1], q[i, 2], q[i, 3] = w, x, y, z
    R[i, 0, 0] = w * w + x * x - y * y - z * z; R[i, 0, 1] = 2.0 * (x * y - w * z); R[i, 0, 2] = 2.0 * (x * z + w * y)
    R[i, 1, 0] = 2.0 * (x * y + w * z); R[i, 1, 1] = w * w - x * x + y * y - z * z; R[i, 1, 2] = 2.0 * (y * z - w * x)
    R[i, 2, 0] = 2.0 * (x * z - w * y); R[i, 2, 1] = 2.0 * (y * z + w * x); R[i, 2, 2] = w * w - x * x - y * y + z * z


@njit(cache=False)
def run_cached(q, R, L, K, X, P, h, steps):
    for i in range(q.shape[0]):
        b0, b1, b2 = lb_of(q[i], L[i])
        fc, ic_, l1, l2, l3 = consts(b0, b1, b2, K[i, 0], K[i, 1], K[i, 2], h)
        rj = -1.0
        x, y, z, px, py, pz = X[i, 0], X[i, 1], X[i, 2], P[i, 0], P[i, 1], P[i, 2]
        for s in range(steps):
            x += h * px  # unit mass, gravity along -z: the exact constant-force step
            y += h * py
            z += h * pz - 0.5 * h * h * 9.81
            pz -= h * 9.81
            cw, cx, cy, cz, l1, l2, l3, rj = step_cached(fc, ic_, l1, l2, l3, rj)
            w0, x0, y0, z0 = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
            w, xx, yy, zz = _qmul(w0, x0, y0, z0, cw, cx, cy, cz)
            n = 1.0 / math.sqrt(w * w + xx * xx + yy * yy + zz * zz)
            store(q, R, i, w * n, xx * n, yy * n, zz * n)
        X[i, 0], X[i, 1], X[i, 2], P[i, 0], P[i, 1], P[i, 2] = x, y, z, px, py, pz


rng = np.random.default_rng(0)
n, steps, h = 10_000, 100, 1e-3
inertia = rng.uniform(0.5, 2.0, (n, 3))
q0 = rng.normal(size=(n, 4)); q0 /= np.linalg.norm(q0, axis=1, keepdims=True)
L0 = rng.normal(size=(n, 3)) * 2.0
K = 1.0 / inertia
X0 = rng.normal(size=(n, 3)); P0 = rng.normal(size=(n, 3))


def kernel():
    st = [X0.copy(), P0.copy(), q0.copy(), quat_to_matrix_np(q0), L0.copy()]
    out = [np.empty((1, n, 3)), np.empty((1, n, 3)), np.empty((1, n, 4)), np.empty((1, n, 3, 3)), np.empty((1, n, 3))]
    t0 = time.perf_counter()
    advance_free(METHOD_CODES["exact"], ORTHO_CODES["normalize"], h, steps, steps, False, np.ones(n), K,
                 np.zeros((n, 3)) + [0, 0, -9.81], np.zeros((n, 3)), *st, *out, n_threads=1)
    return time.perf_counter() - t0, st[2]


def cached():
    q, R, X, P = q0.copy(), quat_to_matrix_np(q0), X0.copy(), P0.copy()
    t0 = time.perf_counter()
    run_cached(q, R, L0, K, X, P, h, steps)
    return time.perf_counter() - t0, q


kernel(); cached()
tk = min(kernel()[0] for _ in range(3))
tc = min(cached()[0] for _ in range(3))
_, qk = kernel()
_, qc = cached()
d = np.minimum(np.abs(qk - qc).max(axis=1), np.abs(qk + qc).max(axis=1)).max()
print(f"10,000 bodies x {steps} steps, one thread: kernel exact {tk / (n * steps) * 1e9:.1f} ns per body-step, "
      f"cached-constants prototype {tc / (n * steps) * 1e9:.1f} ns; max |q_kernel - q_prototype| = {d:.2g}")
