"""The robot's chain in the compiled cycle: frames, adjoints, the TCP Jacobian, the static torque, the damped
pseudo-inverse and the Newton refinement (numba, no allocation: every result goes into a given buffer).

The same equations as the Python path (`service.compensation.FastPredictor`, which calls pinocchio, and
`stiffness.kinematics.statics.Statics`), for a serial chain of revolute joints (joint j's parent is joint j-1):

    oMi_j = oMi_{j-1} * M_j * Rot(a_j, q_j)          M_j the joint's placement, a_j its axis (joint frame)
    oMf   = oMi_{parent(f)} * M_f                    a frame (DH frames, sensor, TCP, the payload's centre)
    J_j   = [w_j x (p_tcp - o_j); w_j],  w_j = R_j a_j  the TCP Jacobian, LOCAL_WORLD_ALIGNED (m, rad)
    tau_s,j = w_j . sum_{k >= j} (c_k - o_j) x (m_k g)  (1 + balancer_j) + w_j . (c_p - o_j) x (m_p g)
              + sum over the identified preload's columns of the static regressor times their weights
    J^+   = J^T (J J^T + λ² I)^-1                    by Cholesky (J J^T + λ² I is positive definite)

`pack` (in `service.kernel.predictor`) reads M_j, a_j, the frames and the masses from pinocchio once.
"""

from __future__ import annotations

import math

from numba import njit

# frame rows of the packed frame table (service.kernel.predictor.pack): DH frames 1..5, sensor, TCP, payload
SENSOR, TCP, PAYLOAD = 5, 6, 7


@njit(cache=True)
def _rot(axis, q, out):
    """Rodrigues: the rotation by q (rad) about the unit ``axis`` into ``out`` (3, 3)."""
    c, s = math.cos(q), math.sin(q)
    v = 1.0 - c
    x, y, z = axis[0], axis[1], axis[2]
    out[0, 0] = c + x * x * v
    out[0, 1] = x * y * v - z * s
    out[0, 2] = x * z * v + y * s
    out[1, 0] = y * x * v + z * s
    out[1, 1] = c + y * y * v
    out[1, 2] = y * z * v - x * s
    out[2, 0] = z * x * v - y * s
    out[2, 1] = z * y * v + x * s
    out[2, 2] = c + z * z * v


@njit(cache=True)
def _mul33(A, B, out):
    for i in range(3):
        for k in range(3):
            out[i, k] = A[i, 0] * B[0, k] + A[i, 1] * B[1, k] + A[i, 2] * B[2, k]


@njit(cache=True)
def forward(q, jR, jp, axis, oR, op, tmp):
    """Joint poses: oR (7, 3, 3), op (7, 3) with row 0 the base and row j joint j, for joints ``q`` (rad)."""
    for j in range(6):
        A = tmp[0]
        _mul33(oR[j], jR[j], A)
        for i in range(3):
            op[j + 1, i] = op[j, i] + oR[j, i, 0] * jp[j, 0] + oR[j, i, 1] * jp[j, 1] + oR[j, i, 2] * jp[j, 2]
        _rot(axis[j], q[j], tmp[1])
        _mul33(A, tmp[1], oR[j + 1])


@njit(cache=True)
def frame(f, fR, fp, fj, oR, op, R, p):
    """The base pose (R (3, 3), p (3,)) of packed frame ``f``."""
    j = fj[f]
    _mul33(oR[j], fR[f], R)
    for i in range(3):
        p[i] = op[j, i] + oR[j, i, 0] * fp[f, 0] + oR[j, i, 1] * fp[f, 1] + oR[j, i, 2] * fp[f, 2]


@njit(cache=True)
def adjoint(R, p, out):
    """The motion adjoint [[R, [p]x R], [0, R]] (6, 6) of the pose (R, p)."""
    for i in range(3):
        for k in range(3):
            out[i, k] = R[i, k]
            out[i + 3, k + 3] = R[i, k]
            out[i + 3, k] = 0.0
    for k in range(3):
        out[0, k + 3] = p[1] * R[2, k] - p[2] * R[1, k]
        out[1, k + 3] = p[2] * R[0, k] - p[0] * R[2, k]
        out[2, k + 3] = p[0] * R[1, k] - p[1] * R[0, k]


@njit(cache=True)
def jacobian(p_tcp, axis, oR, op, J):
    """The TCP Jacobian J (6, 6), [v; w] of the TCP point in base axes per joint rate."""
    for j in range(6):
        R = oR[j + 1]
        wx = R[0, 0] * axis[j, 0] + R[0, 1] * axis[j, 1] + R[0, 2] * axis[j, 2]
        wy = R[1, 0] * axis[j, 0] + R[1, 1] * axis[j, 1] + R[1, 2] * axis[j, 2]
        wz = R[2, 0] * axis[j, 0] + R[2, 1] * axis[j, 1] + R[2, 2] * axis[j, 2]
        dx, dy, dz = p_tcp[0] - op[j + 1, 0], p_tcp[1] - op[j + 1, 1], p_tcp[2] - op[j + 1, 2]
        J[0, j] = wy * dz - wz * dy
        J[1, j] = wz * dx - wx * dz
        J[2, j] = wx * dy - wy * dx
        J[3, j] = wx
        J[4, j] = wy
        J[5, j] = wz


@njit(cache=True)
def _moment_about_axis(w, o, c, f):
    """w . ((c - o) x f)."""
    dx, dy, dz = c[0] - o[0], c[1] - o[1], c[2] - o[2]
    return (w[0] * (dy * f[2] - dz * f[1]) + w[1] * (dz * f[0] - dx * f[2]) + w[2] * (dx * f[1] - dy * f[0]))


@njit(cache=True)
def statics(axis, oR, op, st, lever, c_pay, pre_rows, pre_w, tau_s, w, c, f):
    """tau_s (6,) Nm, signed like the external joint torque (`stiffness.kinematics.statics.Statics.total_at`).

    st: [on, arm_loaded, g (3), payload mass, masses of links 1..6 (6), balancer gains (6)]; lever (6, 3)
    the links' centres of gravity in their joint frames; c_pay (3,) the payload's centre in base axes;
    pre_rows (n,), pre_w (n, 60): the identified preloads' rows and weights on the regressor's columns."""
    for j in range(6):
        tau_s[j] = 0.0
    if st[0] == 0.0:
        return
    g = st[2:5]
    m_pay = st[5]
    for j in range(6):
        R = oR[j + 1]
        for i in range(3):
            w[i] = R[i, 0] * axis[j, 0] + R[i, 1] * axis[j, 1] + R[i, 2] * axis[j, 2]
        o = op[j + 1]
        arm = 0.0
        if st[1] != 0.0:
            for k in range(j, 6):
                Rk = oR[k + 1]
                for i in range(3):
                    c[i] = op[k + 1, i] + Rk[i, 0] * lever[k, 0] + Rk[i, 1] * lever[k, 1] + Rk[i, 2] * lever[k, 2]
                    f[i] = st[6 + k] * g[i]
                arm += _moment_about_axis(w, o, c, f)
        pay = 0.0
        if m_pay > 0.0:
            for i in range(3):
                f[i] = m_pay * g[i]
            pay = _moment_about_axis(w, o, c_pay, f)
        tau_s[j] = arm * (1.0 + st[12 + j]) + pay
    for n in range(len(pre_rows)):
        j = pre_rows[n]
        R = oR[j + 1]
        for i in range(3):
            w[i] = R[i, 0] * axis[j, 0] + R[i, 1] * axis[j, 1] + R[i, 2] * axis[j, 2]
        o = op[j + 1]
        total = 0.0
        for k in range(j, 6):
            Rk = oR[k + 1]
            # the regressor of pinocchio's g(q): -w_j . ((o_k - o_j) x g) per kg, -w_j . ((R_k e_i) x g) per kg m
            total -= pre_w[n, 10 * k] * _moment_about_axis(w, o, op[k + 1], g)
            for i in range(3):
                for r in range(3):
                    c[r] = o[r] + Rk[r, i]
                total -= pre_w[n, 10 * k + 1 + i] * _moment_about_axis(w, o, c, g)
        tau_s[j] += total


@njit(cache=True)
def solve_damped(J, lam, rhs, A, y, out):
    """out = J^T (J J^T + λ² I)^-1 rhs, rhs (6,) (Cholesky of the 6x6, in A)."""
    for i in range(6):
        for k in range(i + 1):
            s = 0.0
            for m in range(6):
                s += J[i, m] * J[k, m]
            A[i, k] = s
        A[i, i] += lam * lam
    for i in range(6):                       # A = L L^T, L in the lower triangle of A
        for k in range(i + 1):
            s = A[i, k]
            for m in range(k):
                s -= A[i, m] * A[k, m]
            if i == k:
                A[i, i] = math.sqrt(s) if s > 0.0 else math.nan
            else:
                A[i, k] = s / A[k, k]
    for i in range(6):                       # L z = rhs
        s = rhs[i]
        for m in range(i):
            s -= A[i, m] * y[m]
        y[i] = s / A[i, i]
    for i in range(5, -1, -1):               # L^T x = z
        s = y[i]
        for m in range(i + 1, 6):
            s -= A[m, i] * y[m]
        y[i] = s / A[i, i]
    for k in range(6):
        s = 0.0
        for i in range(6):
            s += J[i, k] * y[i]
        out[k] = s


@njit(cache=True)
def damped_pinv(J, lam, A, y, e, col, out):
    """out (6, 6) = J^T (J J^T + λ² I)^-1, one column of the identity at a time."""
    for c in range(6):
        for i in range(6):
            e[i] = 1.0 if i == c else 0.0
        solve_damped(J, lam, e, A, y, col)
        for k in range(6):
            out[k, c] = col[k]


@njit(cache=True)
def exp3(v, out):
    """The rotation exp([v]x) (3, 3) of the rotation vector v (rad)."""
    t2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    t = math.sqrt(t2)
    if t < 1e-4:
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
    else:
        a = math.sin(t) / t
        b = (1.0 - math.cos(t)) / t2
    x, y, z = v[0], v[1], v[2]
    out[0, 0] = 1.0 - b * (y * y + z * z)
    out[1, 1] = 1.0 - b * (x * x + z * z)
    out[2, 2] = 1.0 - b * (x * x + y * y)
    out[0, 1] = b * x * y - a * z
    out[1, 0] = b * x * y + a * z
    out[0, 2] = b * x * z + a * y
    out[2, 0] = b * x * z - a * y
    out[1, 2] = b * y * z - a * x
    out[2, 1] = b * y * z + a * x


@njit(cache=True)
def log3(R, out):
    """The rotation vector (3,) of the rotation R (rad; angles below pi)."""
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    c = min(1.0, max(-1.0, c))
    t = math.acos(c)
    k = 0.5 + t * t / 12.0 + 7.0 * t ** 4 / 720.0 if t < 1e-4 else 0.5 * t / math.sin(t)
    out[0] = k * (R[2, 1] - R[1, 2])
    out[1] = k * (R[0, 2] - R[2, 0])
    out[2] = k * (R[1, 0] - R[0, 1])


@njit(cache=True)
def refine(q, dq, dX, iters, lam, jR, jp, axis, fR, fp, fj, Ttcp, oR, op, r3, A, rv, Jk):
    """Newton steps on the full kinematics: dq += J(q+dq)^+ (X_target - X(q + dq)), X_target the TCP at q
    moved by -dX (`FastPredictor.correction`). oR, op, r3 (5, 3, 3), A (6, 6), rv (6, 6), Jk: scratch."""
    Rt, Rk, M, Rm = r3[2], r3[3], r3[4], r3[0]
    pt, e, pk, qk = rv[0], rv[1], rv[2], rv[3]
    for i in range(3):
        pt[i] = Ttcp[i, 3] - dX[i]
        pt[i + 3] = -dX[i + 3]
    exp3(pt[3:], Rm)
    for i in range(3):
        for k in range(3):
            Rk[i, k] = Ttcp[i, k]
    _mul33(Rm, Rk, Rt)
    for _ in range(iters):
        for j in range(6):
            qk[j] = q[j] + dq[j]
        forward(qk, jR, jp, axis, oR, op, r3)
        frame(TCP, fR, fp, fj, oR, op, Rk, pk)
        for i in range(3):
            e[i] = pt[i] - pk[i]
            for k in range(3):
                M[i, k] = Rt[i, 0] * Rk[k, 0] + Rt[i, 1] * Rk[k, 1] + Rt[i, 2] * Rk[k, 2]   # Rt Rk^T
        log3(M, e[3:])
        jacobian(pk, axis, oR, op, Jk)
        solve_damped(Jk, lam, e, A, rv[4], rv[5])
        for j in range(6):
            dq[j] += rv[5, j]
