// rblog.adapters._hook.resolve: the gathered rows of a block of MuJoCo steps -> each step's
// impulses and work per body, the same formulas, in the same order, as the numpy
// StepImpulses.resolve_numpy in rblog/adapters/_mujoco_step.py (the derivation is in
// rblog/adapters/mujoco.py's docstring). Per step k, with c = subtree_com[root[b]] and
// r = xipos[b] - c (c -> centre of mass):
//   S_j (6,)      the unit wrench of dof j about c: [cdof_j(:3); 0] rotational, [(anchor - c) x u;
//                 u] translational (u = cdof_j(3:));
//   tau (3, nv)   applied, passive (minus B (v1 - v0) when MuJoCo integrates damping implicitly),
//                 actuator (plus M a - f + B (v1 - v0) in kind `correction_kind` under implicit);
//   gen_a[b]      sum_j pair[b, j] tau_a,j S_j (pair: +1 on the dof's body, -1 on its parent);
//   W[0] contact  cfrc_ext - xfrc_c (xfrc_c = [tau + r x f; f], about c), W[1..3] = gen
//                 (+ xfrc_c on applied), W[4] joint = cfrc_int[b] - sum_children cfrc_int - sum_a gen_a;
//   then the torques about the centre of mass (tau -= r x f), times h; W[5] integration = 0
//                 (per interval: MujocoRecorder._integration);
//   work_a[b]     (sum over b's dofs of tau_a,j u_j) h (xfrc_applied's work is added in numpy,
//                 _mujoco_step._xfrc_work: einsum's order), and work_joint[b] = (sum over b's dofs of q_joint_j u_j) h, with u = v_work
//                 and q_joint (K, nv) from numpy (StepImpulses._v_work, _joint_forces).
// Sums run over dofs (and children) in ascending order, as numpy's matmul does.
// states() reads the logged states of samples out of the same rows (below).
#include <nanobind/nanobind.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <utility>
#include <vector>

#include "common/py.hpp"

namespace rb {
namespace nb = nanobind;

namespace {

// offsets of the row's fields, in ROW_FIELDS order (rblog/adapters/_mujoco_step.py)
enum RowField {
    F_QPOS, F_QVEL, F_QFRC_APPLIED, F_XFRC_APPLIED, F_XQUAT, F_XIPOS, F_XIMAT, F_XANCHOR,
    F_SUBTREE_COM, F_CDOF, F_CVEL, F_QFRC_PASSIVE, F_QFRC_ACTUATOR, F_QFRC_SMOOTH,
    F_QFRC_CONSTRAINT, F_CFRC_INT, F_CFRC_EXT, N_ROW_FIELDS
};

inline void cross(const double* a, const double* b, double* out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

// whether the six values at w are all +0.0 (bitwise: -0.0 is not)
inline bool positive_zeros(const double* w) {
    std::uint64_t u[6];
    std::memcpy(u, w, sizeof u);
    return (u[0] | u[1] | u[2] | u[3] | u[4] | u[5]) == 0;
}

// whether the n values at x are finite: x 0 is a zero for a finite x and NaN otherwise, so the
// sum of them is zero exactly when all are (four independent sums, which the compiler vectorizes)
inline bool all_finite(const double* x, i64 n) {
    double z[4] = {0.0, 0.0, 0.0, 0.0};
    i64 i = 0;
    for (; i + 4 <= n; i += 4)
        for (int c = 0; c < 4; ++c) z[c] += x[i + c] * 0.0;
    for (; i < n; ++i) z[0] += x[i] * 0.0;
    return (z[0] + z[1]) + (z[2] + z[3]) == 0.0;
}
// whether any of the n values at x is nonzero (a bit besides the sign's)
inline bool any_nonzero(const double* x, i64 n) {
    std::uint64_t bits = 0;
    for (i64 i = 0; i < n; ++i) {
        std::uint64_t u;
        std::memcpy(&u, x + i, 8);
        bits |= u << 1;
    }
    return bits != 0;
}

// IMPULSE_KINDS: contact, applied, passive, actuator, joint, integration
constexpr int N_KINDS = 6;
constexpr int N_WORK = 4;   // WORK_KINDS: applied, passive, actuator, joint

void resolve(nb::handle rows_h, nb::handle offsets_h, nb::handle v1_h, nb::handle v0_h,
             nb::handle ma_h, nb::handle root_h, nb::handle parent_h, nb::handle dof_body_h,
             nb::handle dof_jnt_h, nb::handle dof_trans_h, nb::handle damping_h, double h,
             bool implicit_damping, int correction_kind, nb::handle q_joint_h,
             nb::handle v_work_h, nb::handle w_h, nb::handle work_h) {
    V2<double> rows = v2<double>(rows_h, "rows");
    V1<i64> off = v1<i64>(offsets_h, "offsets");
    V2<double> v1m = v2<double>(v1_h, "v1"), v0m = v2<double>(v0_h, "v0");
    V2<double> ma = v2<double>(ma_h, "Ma");
    V2<double> qj = v2<double>(q_joint_h, "q_joint"), vw = v2<double>(v_work_h, "v_work");
    V1<i64> root = v1<i64>(root_h, "root"), parent = v1<i64>(parent_h, "parent");
    V1<i64> dof_body = v1<i64>(dof_body_h, "dof_body"), dof_jnt = v1<i64>(dof_jnt_h, "dof_jnt");
    V1<i64> dof_trans = v1<i64>(dof_trans_h, "dof_trans");
    V1<double> damping = v1<double>(damping_h, "damping");
    V4<double> W = v4<double>(w_h, "W");
    V3<double> work = v3<double>(work_h, "work");
    const i64 K = rows.n0, nb_ = root.n0, nv = v1m.n1;
    if (off.n0 != N_ROW_FIELDS) throw nb::value_error("resolve: offsets must hold 17 fields");
    if (v1m.n0 != K || v0m.n0 != K || v0m.n1 != nv || parent.n0 != nb_ || dof_body.n0 != nv ||
        dof_jnt.n0 != nv || dof_trans.n0 != nv || damping.n0 != nv || qj.n0 != K ||
        qj.n1 != nv || vw.n0 != K || vw.n1 != nv)
        throw nb::value_error(
            "resolve: v1, v0, q_joint, v_work (K, nv), parent (nbody,), dof_* (nv,) disagree");
    if (W.n0 != K || W.n1 != N_KINDS || W.n2 != nb_ || W.n3 != 6 || work.n0 != K ||
        work.n1 != N_WORK || work.n2 != nb_)
        throw nb::value_error("resolve: W must be (K, 6, nbody, 6) and work (K, 4, nbody)");
    const bool with_ma = ma.n0 > 0;
    if (with_ma && (ma.n0 < K || ma.n1 != nv)) throw nb::value_error("resolve: Ma must be (K, nv)");
    for (i64 f = 0; f < N_ROW_FIELDS; ++f)
        if (off(f) < 0 || off(f) > rows.n1) throw nb::value_error("resolve: offset outside the row");
    for (i64 j = 0; j < nv; ++j)
        if (dof_body(j) < 0 || dof_body(j) >= nb_ || dof_jnt(j) < 0)
            throw nb::value_error("resolve: dof_body or dof_jnt out of range");
    for (i64 b = 0; b < nb_; ++b)
        if (root(b) < 0 || root(b) >= nb_ || parent(b) < 0 || parent(b) >= nb_)
            throw nb::value_error("resolve: root or parent out of range");

    // xfrc_applied anywhere in the block (numpy's `pushed`: the xfrc terms only then)
    bool pushed = false;
    for (i64 k = 0; k < K && !pushed; ++k) pushed = any_nonzero(&rows(k, off(F_XFRC_APPLIED)), 6 * nb_);
    std::vector<double> S(6 * nv), tau(3 * nv), r(3 * nb_), xfc(6 * nb_);
    // each body's gen terms, j ascending: +1 for its own dofs, -1 for its children's (CSR)
    std::vector<i64> term_start(nb_ + 1, 0), term_dof, term_sign;
    {
        std::vector<std::vector<std::pair<i64, i64>>> terms(nb_);
        for (i64 j = 0; j < nv; ++j) {
            const i64 b = dof_body(j), p = parent(b);
            terms[b].push_back({j, 1});
            if (p > 0) terms[p].push_back({j, -1});
        }
        for (i64 b = 0; b < nb_; ++b) {
            for (auto& [j, sg] : terms[b]) {
                term_dof.push_back(j);
                term_sign.push_back(sg);
            }
            term_start[b + 1] = (i64)term_dof.size();
        }
    }
    for (i64 k = 0; k < K; ++k) {
        const double* row = &rows(k, 0);
        const double* com = row + off(F_SUBTREE_COM);
        const double* xipos = row + off(F_XIPOS);
        const double* xf = row + off(F_XFRC_APPLIED);
        const double* cdof = row + off(F_CDOF);
        const double* xanchor = row + off(F_XANCHOR);
        const double* cfrc_ext = row + off(F_CFRC_EXT);
        const double* cfrc_int = row + off(F_CFRC_INT);
        const double* v1 = &v1m(k, 0);
        const double* v0 = &v0m(k, 0);
        const double* u = &vw(k, 0);
        const double* qjk = &qj(k, 0);
        double* Wk = &W(k, 0, 0, 0);  // (6, nbody, 6)
        for (i64 b = 0; b < nb_; ++b)
            for (int c = 0; c < 3; ++c) r[3 * b + c] = xipos[3 * b + c] - com[3 * root(b) + c];
        const bool r_finite = all_finite(r.data(), 3 * nb_);
        // contact
        if (pushed) {
            for (i64 b = 0; b < nb_; ++b) {
                double rf[3];
                cross(&r[3 * b], xf + 6 * b, rf);
                for (int c = 0; c < 3; ++c) {
                    xfc[6 * b + c] = xf[6 * b + 3 + c] + rf[c];
                    xfc[6 * b + 3 + c] = xf[6 * b + c];
                }
                for (int c = 0; c < 6; ++c) Wk[6 * b + c] = cfrc_ext[6 * b + c] - xfc[6 * b + c];
            }
        } else {
            for (i64 i = 0; i < 6 * nb_; ++i) Wk[i] = cfrc_ext[i];
        }
        // S: each dof's unit wrench about its body's c
        for (i64 j = 0; j < nv; ++j) {
            double* s = &S[6 * j];
            const double* cd = cdof + 6 * j;
            if (dof_trans(j)) {
                const double* c = com + 3 * root(dof_body(j));
                const double* an = xanchor + 3 * dof_jnt(j);
                const double arm[3] = {an[0] - c[0], an[1] - c[1], an[2] - c[2]};
                cross(arm, cd + 3, s);
                s[3] = cd[3], s[4] = cd[4], s[5] = cd[5];
            } else {
                s[0] = cd[0], s[1] = cd[1], s[2] = cd[2];
                s[3] = s[4] = s[5] = 0.0;
            }
        }
        // tau (3, nv): applied, passive, actuator
        const double* qa = row + off(F_QFRC_APPLIED);
        const double* qp = row + off(F_QFRC_PASSIVE);
        const double* qu = row + off(F_QFRC_ACTUATOR);
        for (i64 j = 0; j < nv; ++j) {
            tau[j] = qa[j];
            tau[nv + j] = qp[j];
            if (implicit_damping) tau[nv + j] -= damping(j) * (v1[j] - v0[j]);
            tau[2 * nv + j] = qu[j];
        }
        if (with_ma) {  // h D a beyond the dof damping: M a - f - (-B dv)
            const double* sm = row + off(F_QFRC_SMOOTH);
            const double* cn = row + off(F_QFRC_CONSTRAINT);
            const double* mak = &ma(k, 0);
            for (i64 j = 0; j < nv; ++j)
                tau[correction_kind * nv + j] +=
                    mak[j] - sm[j] - cn[j] + damping(j) * (v1[j] - v0[j]);
        }
        // gen (3, nbody, 6), each dof's wrench on its body and the opposite on its parent, written
        // straight into W[1..3]: body b's sum over `terms` (its dofs and its children's, j
        // ascending: the order of numpy's sum over dofs) from +0.0. A term whose tau is zero is
        // left out when every S is finite: t S is then a zero, and adding or subtracting a zero
        // leaves a sum that starts at +0.0 as it is (such a sum is never -0.0).
        const bool finite = all_finite(S.data(), 6 * nv);
        for (int a = 0; a < 3; ++a) {
            double* g = Wk + (1 + a) * nb_ * 6;
            const double* ta = &tau[a * nv];
            for (i64 b = 0; b < nb_; ++b) {
                double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
                for (i64 e = term_start[b]; e < term_start[b + 1]; ++e) {
                    const i64 j = term_dof[e];
                    const double t = ta[j];
                    if (finite && t == 0.0) continue;
                    const double* sj = &S[6 * j];
                    if (term_sign[e] > 0)
                        for (int c = 0; c < 6; ++c) acc[c] += t * sj[c];
                    else
                        for (int c = 0; c < 6; ++c) acc[c] -= t * sj[c];
                }
                for (int c = 0; c < 6; ++c) g[6 * b + c] = acc[c];
            }
        }
        // joint: the net of cfrc_int (the body's own minus its children's), minus gen
        double* Wj = Wk + 4 * nb_ * 6;
        for (i64 i = 0; i < 6; ++i) Wj[i] = 0.0;  // the world's row of numpy's `net` is zero
        for (i64 b = 1; b < nb_; ++b)
            for (int c = 0; c < 6; ++c) Wj[6 * b + c] = cfrc_int[6 * b + c];
        for (i64 b = 1; b < nb_; ++b) {
            const i64 p = parent(b);
            if (p > 0)
                for (int c = 0; c < 6; ++c) Wj[6 * p + c] -= cfrc_int[6 * b + c];
        }
        {
            const double* g0 = Wk + nb_ * 6;
            const double* g1 = Wk + 2 * nb_ * 6;
            const double* g2 = Wk + 3 * nb_ * 6;
            for (i64 i = 0; i < 6 * nb_; ++i) Wj[i] -= g0[i] + g1[i] + g2[i];
        }
        if (pushed)
            for (i64 i = 0; i < 6 * nb_; ++i) Wk[nb_ * 6 + i] += xfc[i];
        // torques about the centre of mass, then impulses; the integration kind 0
        for (i64 i = 0; i < 6 * nb_; ++i) Wk[5 * nb_ * 6 + i] = 0.0;
        // (a row of six +0.0 at a finite r stays six +0.0: r x 0 is a zero, +0.0 minus a zero is
        // +0.0, times h > 0 too; such rows are left as they are)
        for (int a = 0; a < 5; ++a)
            for (i64 b = 0; b < nb_; ++b) {
                double* w = Wk + (a * nb_ + b) * 6;
                if (r_finite && positive_zeros(w)) continue;
                double rf[3];
                cross(&r[3 * b], w + 3, rf);
                for (int c = 0; c < 3; ++c) w[c] -= rf[c];
                for (int c = 0; c < 6; ++c) w[c] *= h;
            }
        // work (4, nbody)
        double* wk = &work(k, 0, 0);
        for (i64 i = 0; i < N_WORK * nb_; ++i) wk[i] = 0.0;
        // (a zero tau at a finite u adds a zero to a sum from +0.0: left out, as in gen)
        const bool u_finite = all_finite(u, nv);
        for (int a = 0; a < 3; ++a)
            for (i64 j = 0; j < nv; ++j) {
                const double t = tau[a * nv + j];
                if (!(u_finite && t == 0.0)) wk[a * nb_ + dof_body(j)] += t * u[j];
            }
        for (i64 j = 0; j < nv; ++j) wk[3 * nb_ + dof_body(j)] += qjk[j] * u[j];
        for (i64 i = 0; i < N_WORK * nb_; ++i) wk[i] *= h;
    }
}

// The logged states of samples whose state is the start of a gathered step (row rr[m]), as
// MujocoRecorder._states_numpy: for sample slot i[m] and logged body n (MuJoCo body ids[n]),
//   x = xipos, R = ximat, q = xquat (x) iquat[n] (Hamilton, scalar first), w = cvel(:3),
//   v = cvel(3:) + w x (x - subtree_com[root])   (cvel is about the root's subtree com).
void states(nb::handle rows_h, nb::handle offsets_h, nb::handle rr_h, nb::handle slot_h,
            nb::handle ids_h, nb::handle root_h, nb::handle iquat_h, nb::handle x_h,
            nb::handle r_h, nb::handle q_h, nb::handle v_h, nb::handle w_h) {
    V2<double> rows = v2<double>(rows_h, "rows");
    V1<i64> off = v1<i64>(offsets_h, "offsets"), rr = v1<i64>(rr_h, "rr");
    V1<i64> slot = v1<i64>(slot_h, "slot"), ids = v1<i64>(ids_h, "ids");
    V1<i64> root = v1<i64>(root_h, "root");
    V2<double> iquat = v2<double>(iquat_h, "iquat");
    V3<double> X = v3<double>(x_h, "x"), Q = v3<double>(q_h, "q"), V = v3<double>(v_h, "v");
    V3<double> Wv = v3<double>(w_h, "w");
    V4<double> R = v4<double>(r_h, "r");
    const i64 M = rr.n0, N = ids.n0, nb_ = root.n0;
    if (off.n0 != N_ROW_FIELDS || slot.n0 != M || iquat.n0 != N || iquat.n1 != 4)
        throw nb::value_error("states: offsets (17,), slot (M,), iquat (N, 4) disagree");
    const i64 cap = X.n0;
    if (X.n1 != N || X.n2 != 3 || R.n0 != cap || R.n1 != N || R.n2 != 3 || R.n3 != 3 ||
        Q.n0 != cap || Q.n1 != N || Q.n2 != 4 || V.n0 != cap || V.n1 != N || V.n2 != 3 ||
        Wv.n0 != cap || Wv.n1 != N || Wv.n2 != 3)
        throw nb::value_error("states: x, v, w (C, N, 3), r (C, N, 3, 3), q (C, N, 4) disagree");
    for (i64 n = 0; n < N; ++n)
        if (ids(n) < 0 || ids(n) >= nb_) throw nb::value_error("states: ids out of range");
    for (i64 b = 0; b < nb_; ++b)
        if (root(b) < 0 || root(b) >= nb_) throw nb::value_error("states: root out of range");
    for (i64 m = 0; m < M; ++m) {
        if (rr(m) < 0 || rr(m) >= rows.n0 || slot(m) < 0 || slot(m) >= cap)
            throw nb::value_error("states: row or slot out of range");
        const double* row = &rows(rr(m), 0);
        const double* xipos = row + off(F_XIPOS);
        const double* ximat = row + off(F_XIMAT);
        const double* xquat = row + off(F_XQUAT);
        const double* cvel = row + off(F_CVEL);
        const double* com = row + off(F_SUBTREE_COM);
        const i64 i = slot(m);
        for (i64 n = 0; n < N; ++n) {
            const i64 b = ids(n);
            double* x = &X(i, n, 0);
            for (int c = 0; c < 3; ++c) x[c] = xipos[3 * b + c];
            for (int c = 0; c < 9; ++c) (&R(i, n, 0, 0))[c] = ximat[9 * b + c];
            const double* a = xquat + 4 * b;
            const double* e = &iquat(n, 0);
            double* q = &Q(i, n, 0);
            q[0] = a[0] * e[0] - a[1] * e[1] - a[2] * e[2] - a[3] * e[3];
            q[1] = a[0] * e[1] + a[1] * e[0] + a[2] * e[3] - a[3] * e[2];
            q[2] = a[0] * e[2] - a[1] * e[3] + a[2] * e[0] + a[3] * e[1];
            q[3] = a[0] * e[3] + a[1] * e[2] - a[2] * e[1] + a[3] * e[0];
            const double* cv = cvel + 6 * b;
            const double* c0 = com + 3 * root(b);
            const double arm[3] = {x[0] - c0[0], x[1] - c0[1], x[2] - c0[2]};
            double wa[3];
            cross(cv, arm, wa);
            double* w = &Wv(i, n, 0);
            double* v = &V(i, n, 0);
            for (int c = 0; c < 3; ++c) {
                w[c] = cv[c];
                v[c] = cv[3 + c] + wa[c];
            }
        }
    }
}

// The integration kind of each sample's interval and the samples' momenta, as
// MujocoRecorder._integration_numpy (rblog/adapters/mujoco.py), same formulas, same order: for
// sample k and logged body n (MuJoCo body b = ids[n]), R = r[k, n], w = w[k, n]:
//   p = m v;  w_b = R^T w (sum over j = 0, 1, 2 of R[j][i] w[j]);  L = R (I w_b)
//   F = (((W_0 + W_1) + W_2) + W_3) + W_4          (the kinds before integration, at body b)
//   W_5 = [L - L_prev - F_ang;  ((p - p_prev) - (m g) dt) - F_lin]   where `logged[n]`, else 0
// with dt = (step_k - step_prev) h; the previous sample's (step, p, L) is the last of the block
// before (prev_*), or sample 0's own when `has_prev` is false (the run's first: no interval).
void integration(nb::handle w_h, nb::handle ids_h, nb::handle mass_h, nb::handle inertia_h,
                 nb::handle gravity_h, nb::handle logged_h, nb::handle steps_h, double h,
                 bool has_prev, i64 prev_step, nb::handle prev_p_h, nb::handle prev_l_h,
                 nb::handle r_h, nb::handle v_h, nb::handle wv_h, nb::handle p_h, nb::handle l_h) {
    V4<double> W = v4<double>(w_h, "W");
    V1<i64> ids = v1<i64>(ids_h, "ids"), logged = v1<i64>(logged_h, "logged");
    V1<i64> steps = v1<i64>(steps_h, "steps");
    V1<double> mass = v1<double>(mass_h, "mass"), grav = v1<double>(gravity_h, "gravity");
    V2<double> inertia = v2<double>(inertia_h, "inertia");
    V2<double> pp = v2<double>(prev_p_h, "prev_p"), pl = v2<double>(prev_l_h, "prev_L");
    V4<double> R = v4<double>(r_h, "r");
    V3<double> V = v3<double>(v_h, "v"), Wv = v3<double>(wv_h, "w");
    V3<double> P = v3<double>(p_h, "p"), L = v3<double>(l_h, "L");
    const i64 K = W.n0, NB = W.n2, N = ids.n0;
    if (W.n1 != N_KINDS || W.n3 != 6 || steps.n0 != K || mass.n0 != N || logged.n0 != N ||
        inertia.n0 != N || inertia.n1 != 3 || grav.n0 != 3 || pp.n0 != N || pp.n1 != 3 ||
        pl.n0 != N || pl.n1 != 3)
        throw nb::value_error("integration: W (K, 6, nbody, 6), steps (K,), ids, mass, logged "
                              "(N,), inertia, prev_p, prev_L (N, 3), gravity (3,) disagree");
    if (R.n0 < K || R.n1 != N || R.n2 != 3 || R.n3 != 3 || V.n0 < K || V.n1 != N || V.n2 != 3 ||
        Wv.n0 < K || Wv.n1 != N || Wv.n2 != 3 || P.n0 != K || P.n1 != N || P.n2 != 3 ||
        L.n0 != K || L.n1 != N || L.n2 != 3)
        throw nb::value_error("integration: r (>= K, N, 3, 3), v, w (>= K, N, 3), p, L "
                              "(K, N, 3) disagree");
    for (i64 n = 0; n < N; ++n)
        if (ids(n) < 0 || ids(n) >= NB) throw nb::value_error("integration: ids out of range");
    constexpr int I_INT = 5;  // IMPULSE_KINDS.index("integration")
    for (i64 k = 0; k < K; ++k)
        for (i64 n = 0; n < N; ++n) {
            const double* r = &R(k, n, 0, 0);
            const double* w = &Wv(k, n, 0);
            double* p = &P(k, n, 0);
            double* l = &L(k, n, 0);
            double wb[3], iw[3];
            for (int c = 0; c < 3; ++c) p[c] = mass(n) * V(k, n, c);
            for (int i = 0; i < 3; ++i) wb[i] = r[i] * w[0] + r[3 + i] * w[1] + r[6 + i] * w[2];
            for (int i = 0; i < 3; ++i) iw[i] = inertia(n, i) * wb[i];
            for (int i = 0; i < 3; ++i)
                l[i] = r[3 * i] * iw[0] + r[3 * i + 1] * iw[1] + r[3 * i + 2] * iw[2];
        }
    for (i64 k = 0; k < K; ++k) {
        const bool first = k == 0;
        const i64 s0 = first ? (has_prev ? prev_step : steps(0)) : steps(k - 1);
        const double dt = double(steps(k) - s0) * h;
        for (i64 n = 0; n < N; ++n) {
            double* out = &W(k, I_INT, ids(n), 0);
            if (!logged(n)) {
                for (int c = 0; c < 6; ++c) out[c] = 0.0;
                continue;
            }
            const double* p0 = first ? (has_prev ? &pp(n, 0) : &P(0, n, 0)) : &P(k - 1, n, 0);
            const double* l0 = first ? (has_prev ? &pl(n, 0) : &L(0, n, 0)) : &L(k - 1, n, 0);
            double f[6];
            for (int c = 0; c < 6; ++c) {
                f[c] = W(k, 0, ids(n), c) + W(k, 1, ids(n), c);
                for (int a = 2; a < I_INT; ++a) f[c] += W(k, a, ids(n), c);
            }
            for (int c = 0; c < 3; ++c) {
                out[3 + c] = ((P(k, n, c) - p0[c]) - (mass(n) * grav(c)) * dt) - f[3 + c];
                out[c] = (L(k, n, c) - l0[c]) - f[c];
            }
        }
    }
}

// The generalized force of the joints' non-ideal constraints, StepImpulses._joint_forces:
// q_joint[k, j] = qfrc_constraint[k, j] - sum_s cdof[k, j, s] below[k, j, s], below[k, j] the
// contact wrenches (K, nbody, 6) summed over the subtree of dof j's body. numpy's
// matmul(subtree, contact) (a 0/1 matrix) sums the subtree's bodies in ascending order from
// +0.0; `mode` 0: the whole q_joint (the cdof sum in einsum's order, below); 1: `below` alone,
// written into below (K, nv, 6) (the caller takes the einsum). `members` (CSR over bodies:
// start (nbody + 1,), body (M,) ascending) are the subtree's bodies; contact (K, nbody, 6), or
// empty: the rows' cfrc_ext.
void joint_forces(nb::handle rows_h, nb::handle offsets_h, nb::handle contact_h,
                  nb::handle start_h, nb::handle members_h, nb::handle dof_body_h, int mode,
                  nb::handle below_h, nb::handle q_h) {
    V2<double> rows = v2<double>(rows_h, "rows");
    V1<i64> off = v1<i64>(offsets_h, "offsets");
    V3<double> con = v3<double>(contact_h, "contact");
    V1<i64> start = v1<i64>(start_h, "start"), mem = v1<i64>(members_h, "members");
    V1<i64> dof_body = v1<i64>(dof_body_h, "dof_body");
    V3<double> below = v3<double>(below_h, "below");
    V2<double> q = v2<double>(q_h, "q_joint");
    const i64 K = rows.n0, nv = dof_body.n0, nb_ = start.n0 - 1;
    if (off.n0 != N_ROW_FIELDS) throw nb::value_error("joint_forces: offsets must hold 17 fields");
    for (i64 f = 0; f < N_ROW_FIELDS; ++f)
        if (off(f) < 0 || off(f) > rows.n1) throw nb::value_error("joint_forces: offset outside the row");
    const bool own = con.n0 > 0;
    if (own && (con.n0 != K || con.n1 != nb_ || con.n2 != 6))
        throw nb::value_error("joint_forces: contact must be (K, nbody, 6) or empty");
    if (nb_ < 0 || start(0) != 0 || start(nb_) != mem.n0)
        throw nb::value_error("joint_forces: bad subtree lists");
    for (i64 b = 0; b < nb_; ++b)
        if (start(b) > start(b + 1)) throw nb::value_error("joint_forces: bad subtree lists");
    for (i64 i = 0; i < mem.n0; ++i)
        if (mem(i) < 0 || mem(i) >= nb_) throw nb::value_error("joint_forces: member out of range");
    for (i64 j = 0; j < nv; ++j)
        if (dof_body(j) < 0 || dof_body(j) >= nb_) throw nb::value_error("joint_forces: dof_body out of range");
    if (off(F_CFRC_EXT) + 6 * nb_ > rows.n1 || off(F_CDOF) + 6 * nv > rows.n1 ||
        off(F_QFRC_CONSTRAINT) + nv > rows.n1)
        throw nb::value_error("joint_forces: a field outside the row");
    if (mode == 1 ? (below.n0 != K || below.n1 != nv || below.n2 != 6)
                  : (q.n0 != K || q.n1 != nv))
        throw nb::value_error("joint_forces: below (K, nv, 6) or q_joint (K, nv) disagree");
    for (i64 k = 0; k < K; ++k) {
        const double* row = &rows(k, 0);
        const double* c = own ? &con(k, 0, 0) : row + off(F_CFRC_EXT);
        const double* cdof = row + off(F_CDOF);
        const double* qc = row + off(F_QFRC_CONSTRAINT);
        for (i64 j = 0; j < nv; ++j) {
            const i64 b = dof_body(j);
            double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
            for (i64 i = start(b); i < start(b + 1); ++i)
                for (int e = 0; e < 6; ++e) acc[e] = acc[e] + c[6 * mem(i) + e];
            if (mode == 1) {
                for (int e = 0; e < 6; ++e) below(k, j, e) = acc[e];
            } else {
                // numpy's einsum order on x86-64 (its baseline, two float64 lanes): the even
                // and the odd products each summed from +0.0, then the two sums
                const double* u = cdof + 6 * j;
                double lane0 = 0.0, lane1 = 0.0;
                for (int e = 0; e < 6; e += 2) {
                    lane0 = lane0 + u[e] * acc[e];
                    lane1 = lane1 + u[e + 1] * acc[e + 1];
                }
                q(k, j) = qc[j] - (lane0 + lane1);
            }
        }
    }
}

}  // namespace

void bind_resolve(nb::module_& m) {
    m.def("joint_forces", &joint_forces,
          "joint_forces(rows, offsets, contact, start, members, dof_body, mode, below, q_joint): "
          "StepImpulses._joint_forces (mode 0: q_joint; 1: the subtree sums `below` alone) "
          "(csrc/adapters/mujoco_resolve.cpp)");
    m.def("integration", &integration,
          "integration(W, ids, mass, inertia, gravity, logged, steps, h, has_prev, prev_step, "
          "prev_p, prev_L, r, v, w, p, L): the integration kind into W[:, 5, ids] and the samples' "
          "momenta p, L (csrc/adapters/mujoco_resolve.cpp)");
    m.def("states", &states,
          "states(rows, offsets, rr, slot, ids, root, iquat, x, r, q, v, w): the states of the "
          "samples in slots `slot` from the rows `rr` (csrc/adapters/mujoco_resolve.cpp)");
    m.def("resolve", &resolve,
          "resolve(rows, offsets, v1, v0, Ma, root, parent, dof_body, dof_jnt, dof_trans, damping, "
          "h, implicit_damping, correction_kind, q_joint, v_work, W, work): a block's impulses W "
          "(K, 6, nbody, 6) and work (K, 4, nbody), written into W and work "
          "(csrc/adapters/mujoco_resolve.cpp)");
}

}  // namespace rb
