# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The compiled iLQR iteration for the Qube: the same algorithm as `qube_suite.devices.qube.controllers.ilqr`, in C loops.

`benchmarks/ilqr.py` measures why: at 250 Hz with a 0.8 s horizon (200 knots) one
iteration costs milliseconds in numpy (Python loops over 4 x 4 matrices) and
tens of microseconds here. The model, the cost and the steps are documented in
`qube_suite.devices.qube.controllers.ilqr`; tests check that both give the same iterates.
"""

from libc.math cimport cos, sin, fabs, round, INFINITY, M_PI

import numpy as np


cdef double MAX_REGULARIZATION = 10.0
"""Largest mu (added to Q_uu, in cost units per V^2): larger ones would only shrink the step."""


cdef struct Model:
    double base_inertia, swing_inertia, coupling, pendulum_inertia, gravity_torque
    double arm_damping, pendulum_damping, torque_per_volt, back_emf


cdef struct Cost:
    double pendulum, arm, arm_speed, pendulum_speed, voltage, arm_limit, limit_weight, lean_limit, lean_weight
    double terminal


cdef void dynamics(const Model* m, const double* x, double u, double* f, double* J, bint jacobian) noexcept nogil:
    """f = dx/dt at (x, u); with `jacobian`, J (4 x 5, row-major) = df/d(x, u)."""
    cdef double s = sin(x[1]), c = cos(x[1]), w = x[2], v = x[3]
    cdef double K = m.swing_inertia, C = m.coupling, P = m.pendulum_inertia
    cdef double sc = s * c
    cdef double m11 = m.base_inertia + K * s * s
    cdef double r1 = (m.torque_per_volt * (u - m.back_emf * w) - m.arm_damping * w - 2.0 * K * sc * w * v
                      - C * s * v * v)
    cdef double r2 = K * sc * w * w + m.gravity_torque * s - m.pendulum_damping * v
    cdef double det = m11 * P - C * C * c * c
    cdef double n1 = P * r1 + C * c * r2, n2 = m11 * r2 + C * c * r1
    cdef double a1 = n1 / det, a2 = n2 / det
    f[0] = w
    f[1] = v
    f[2] = a1
    f[3] = a2
    if not jacobian:
        return
    cdef double cc_ss = c * c - s * s
    cdef double r1_a = -2.0 * K * cc_ss * w * v - C * c * v * v
    cdef double r2_a = K * cc_ss * w * w + m.gravity_torque * c
    cdef double m11_a = 2.0 * K * sc
    cdef double det_a = m11_a * P + 2.0 * C * C * sc
    cdef double n1_a = P * r1_a - C * s * r2 + C * c * r2_a
    cdef double n2_a = m11_a * r2 + m11 * r2_a - C * s * r1 + C * c * r1_a
    cdef double r1_w = -m.torque_per_volt * m.back_emf - m.arm_damping - 2.0 * K * sc * v
    cdef double r2_w = 2.0 * K * sc * w
    cdef double r1_v = -2.0 * K * sc * w - 2.0 * C * s * v
    cdef double r2_v = -m.pendulum_damping
    cdef int i
    for i in range(20):
        J[i] = 0.0
    J[2] = 1.0
    J[8] = 1.0
    J[11] = (n1_a - a1 * det_a) / det
    J[12] = (P * r1_w + C * c * r2_w) / det
    J[13] = (P * r1_v + C * c * r2_v) / det
    J[14] = P * m.torque_per_volt / det
    J[16] = (n2_a - a2 * det_a) / det
    J[17] = (m11 * r2_w + C * c * r1_w) / det
    J[18] = (m11 * r2_v + C * c * r1_v) / det
    J[19] = C * c * m.torque_per_volt / det


cdef void rk4_step(const Model* m, const double* x, double u, double h, double* out, double* D,
               bint jacobian) noexcept nogil:
    """One RK4 step of length h from (x, u) into `out`; with `jacobian`, D (4 x 5) = d out / d(x, u)."""
    cdef double k[4][4]
    cdef double J[20]
    cdef double dk[4][20]
    cdef double Dx[20]
    cdef double xs[4]
    cdef double fractions[4]
    fractions[:] = [0.0, 0.5, 0.5, 1.0]
    cdef int stage, i, j, l
    cdef double acc
    for stage in range(4):
        for i in range(4):
            xs[i] = x[i] if stage == 0 else x[i] + fractions[stage] * h * k[stage - 1][i]
        dynamics(m, xs, u, k[stage], J, jacobian)
        if jacobian:
            # Dx = d xs / d(x, u) = [I 0] + fraction h dk[stage - 1]
            for i in range(4):
                for j in range(5):
                    Dx[5 * i + j] = (1.0 if i == j else 0.0) + (
                        fractions[stage] * h * dk[stage - 1][5 * i + j] if stage > 0 else 0.0)
            for i in range(4):
                for j in range(5):
                    acc = J[5 * i + 4] if j == 4 else 0.0
                    for l in range(4):
                        acc = acc + J[5 * i + l] * Dx[5 * l + j]
                    dk[stage][5 * i + j] = acc
    for i in range(4):
        out[i] = x[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i])
    if jacobian:
        for i in range(20):
            D[i] = (1.0 if (i % 5 == i // 5) else 0.0) + h / 6.0 * (
                dk[0][i] + 2.0 * dk[1][i] + 2.0 * dk[2][i] + dk[3][i])


cdef double stage_cost(const Cost* q, const double* x, double u, double r, double rd, double scale,
                       double* lx, double* lxx, double* lu, double* luu, bint derivatives) noexcept nogil:
    """scale * l(x, u): the running cost (see `ilqr.py`); derivatives into lx (4), lxx (4 x 4 diagonal), lu,
    luu."""
    cdef double e = x[0] - r, ed = x[2] - rd, over = fabs(x[0]) - q.arm_limit
    cdef double lean = x[1] - 2.0 * M_PI * round(x[1] / (2.0 * M_PI))  # from the nearest upright
    cdef double leaning = fabs(lean) - q.lean_limit
    cdef double value = (q.pendulum * (1.0 - cos(x[1])) + q.arm * e * e + q.arm_speed * ed * ed
                         + q.pendulum_speed * x[3] * x[3] + q.voltage * u * u)
    if over > 0.0:
        value += q.limit_weight * over * over
    if leaning > 0.0:
        value += q.lean_weight * leaning * leaning
    if derivatives:
        lx[0] = scale * 2.0 * q.arm * e
        lx[1] = scale * q.pendulum * sin(x[1])
        lx[2] = scale * 2.0 * q.arm_speed * ed
        lx[3] = scale * 2.0 * q.pendulum_speed * x[3]
        lxx[0] = scale * 2.0 * q.arm
        lxx[1] = scale * q.pendulum * cos(x[1])
        lxx[2] = scale * 2.0 * q.arm_speed
        lxx[3] = scale * 2.0 * q.pendulum_speed
        if over > 0.0:
            lx[0] += scale * 2.0 * q.limit_weight * over * (1.0 if x[0] > 0.0 else -1.0)
            lxx[0] += scale * 2.0 * q.limit_weight
        if leaning > 0.0:
            lx[1] += scale * 2.0 * q.lean_weight * leaning * (1.0 if lean > 0.0 else -1.0)
            lxx[1] += scale * 2.0 * q.lean_weight
        lu[0] = scale * 2.0 * q.voltage * u
        luu[0] = scale * 2.0 * q.voltage
    return scale * value


cdef class Kernel:
    """Plan state for `knots` steps of `timestep` s: voltages U, states X, gains k and K, derivatives.

    `iterate(x0, reference, reference_speed)` does one iLQR iteration (rollout of the current
    plan with its gains, derivatives, backward pass, line search) and returns the plan's cost.
    """

    cdef Model model
    cdef Cost cost
    cdef public int knots
    cdef public double timestep, voltage_limit, regularization
    cdef public object U, X, k, K, reference, reference_speed
    cdef double[:] _U, _k, _Unew
    cdef double[:, :] _X, _K, _Xnew, _D
    cdef double[:] _r, _rd

    def __init__(self, model, cost, int knots, double timestep, double voltage_limit):
        self.model = Model(model.base_inertia, model.swing_inertia, model.coupling, model.pendulum_inertia,
                           model.gravity_torque, model.arm_damping, model.pendulum_damping,
                           model.torque_per_volt, model.back_emf)
        self.cost = Cost(cost.pendulum, cost.arm, cost.arm_speed, cost.pendulum_speed, cost.voltage,
                         cost.arm_limit, cost.limit_weight, INFINITY, cost.lean_weight, cost.terminal)
        self.knots, self.timestep, self.voltage_limit = knots, timestep, voltage_limit
        self.regularization = 0.0
        self.U, self.k = np.zeros(knots), np.zeros(knots)
        self.X, self.K = np.zeros((knots + 1, 4)), np.zeros((knots, 4))
        self._U, self._k, self._X, self._K = self.U, self.k, self.X, self.K
        self._Unew, self._Xnew = np.zeros(knots), np.zeros((knots + 1, 4))
        self._D = np.zeros((knots, 20))
        self.reference, self.reference_speed = np.zeros(knots + 1), np.zeros(knots + 1)
        self._r, self._rd = self.reference, self.reference_speed

    @property
    def lean_limit(self):
        """The pendulum's lean from upright (rad) beyond which it pays `lean_weight` times the square of
        the excess; infinite (the start): no such cost."""
        return self.cost.lean_limit

    @lean_limit.setter
    def lean_limit(self, double value):
        self.cost.lean_limit = value

    def step(self, x, double u, double h):
        """(RK4 step of length h from x under u, its Jacobian (4 x 5) with respect to (x, u))."""
        cdef double[:] xv = np.ascontiguousarray(x, dtype=np.float64)
        out, D = np.zeros(4), np.zeros(20)
        cdef double[:] o = out, d = D
        rk4_step(&self.model, &xv[0], u, h, &o[0], &d[0], True)
        return out, D.reshape(4, 5)

    def shift(self, int knots=1):
        """Move the plan `knots` knots on, repeating its last voltage and gain."""
        if knots <= 0:
            return
        knots = min(knots, self.knots)
        self.U[:-knots] = self.U[knots:].copy()
        self.U[-knots:] = self.U[-knots - 1] if knots < self.knots else 0.0
        self.K[:-knots] = self.K[knots:].copy()
        self.X[:-knots] = self.X[knots:].copy()
        self.X[-knots:] = self.X[-knots - 1]

    cdef double _rollout(self, double[:] x0, double[:, :] X, double[:] U, double[:, :] Xref, double[:] Uref,
                         double step_size, bint feedback) noexcept nogil:
        """Simulate from x0 with u = Uref + step_size k + K (x - Xref), clipped; fill X and U; return cost."""
        cdef int n, i
        cdef double u, total = 0.0
        cdef double unused[20]
        for i in range(4):
            X[0, i] = x0[i]
        for n in range(self.knots):
            u = Uref[n]
            if feedback:
                u = u + step_size * self._k[n]
                for i in range(4):
                    u = u + self._K[n, i] * (X[n, i] - Xref[n, i])
            u = min(max(u, -self.voltage_limit), self.voltage_limit)
            U[n] = u
            total += stage_cost(&self.cost, &X[n, 0], u, self._r[n], self._rd[n], self.timestep,
                                NULL, NULL, NULL, NULL, False)
            rk4_step(&self.model, &X[n, 0], u, self.timestep, &X[n + 1, 0], unused, False)
        total += stage_cost(&self.cost, &X[self.knots, 0], 0.0, self._r[self.knots], self._rd[self.knots],
                            self.cost.terminal, NULL, NULL, NULL, NULL, False)
        return total

    def rollout_cost(self, x0, reference, reference_speed):
        """The cost of the plan from the state x0, its own feedback applied (as `iterate` starts),
        towards the arm reference (rad) and its speed (rad/s); the plan is left as it is."""
        cdef double[:] x = np.ascontiguousarray(x0, dtype=np.float64)
        self.reference[:] = reference
        self.reference_speed[:] = reference_speed
        return self._rollout(x, self._Xnew, self._Unew, self._X, self._U, 0.0, True)

    def iterate(self, x0, reference, reference_speed, int line_search=6):
        """One iLQR iteration from the state x0 towards the arm reference (rad, per knot or one value)
        and its speed (rad/s); returns the cost of the plan it leaves (the old one if none was better)."""
        cdef double[:] x = np.ascontiguousarray(x0, dtype=np.float64)
        self.reference[:] = reference
        self.reference_speed[:] = reference_speed
        cdef int N = self.knots, n, i, j, l, attempt
        cdef double cost, new_cost, step_size, h = self.timestep
        cdef double lx[4]
        cdef double lxx[4]
        cdef double lu, luu, Qu, Quu, Vx[4], Vxx[4][4], Qx[4], Qux[4], Qxx[4][4], VB[4], VA[4][4]
        cdef double *D
        cdef double kk, acc, expected
        cdef bint solved = False
        # the current plan, its own feedback applied from the new start
        cost = self._rollout(x, self._Xnew, self._Unew, self._X, self._U, 0.0, True)
        if not cost < INFINITY:  # a plan that diverged (NaN or inf): start again from rest at 0 V
            self.U[:] = 0.0
            self.K[:] = 0.0
            self.regularization = 0.0
            cost = self._rollout(x, self._Xnew, self._Unew, self._X, self._U, 0.0, False)
        self._X[:, :] = self._Xnew
        self._U[:] = self._Unew
        with nogil:  # derivatives along the plan
            for n in range(N):
                rk4_step(&self.model, &self._X[n, 0], self._U[n], h, lx, &self._D[n, 0], True)
            while True:
                stage_cost(&self.cost, &self._X[N, 0], 0.0, self._r[N], self._rd[N], self.cost.terminal,
                           lx, lxx, &lu, &luu, True)
                for i in range(4):
                    Vx[i] = lx[i]
                    for j in range(4):
                        Vxx[i][j] = lxx[i] if i == j else 0.0
                expected = 0.0
                for n in range(N - 1, -1, -1):
                    stage_cost(&self.cost, &self._X[n, 0], self._U[n], self._r[n], self._rd[n], h,
                               lx, lxx, &lu, &luu, True)
                    D = &self._D[n, 0]
                    # VA = Vxx A, VB = Vxx B
                    for i in range(4):
                        VB[i] = 0.0
                        for j in range(4):
                            VB[i] += Vxx[i][j] * D[5 * j + 4]
                            acc = 0.0
                            for l in range(4):
                                acc += Vxx[i][l] * D[5 * l + j]
                            VA[i][j] = acc
                    Qu = lu
                    Quu = luu + self.regularization
                    for i in range(4):
                        Qu += D[5 * i + 4] * Vx[i]
                        Quu += D[5 * i + 4] * VB[i]
                    if Quu <= 1e-12:
                        break
                    for j in range(4):
                        Qx[j] = lx[j]
                        Qux[j] = 0.0
                        for i in range(4):
                            Qx[j] += D[5 * i + j] * Vx[i]
                            Qux[j] += D[5 * i + 4] * VA[i][j]
                        for l in range(4):
                            acc = lxx[j] if j == l else 0.0
                            for i in range(4):
                                acc += D[5 * i + j] * VA[i][l]
                            Qxx[j][l] = acc
                    kk = -Qu / Quu
                    if self._U[n] + kk > self.voltage_limit or self._U[n] + kk < -self.voltage_limit:
                        kk = min(max(self._U[n] + kk, -self.voltage_limit), self.voltage_limit) - self._U[n]
                        for i in range(4):
                            self._K[n, i] = 0.0
                    else:
                        for i in range(4):
                            self._K[n, i] = -Qux[i] / Quu
                    self._k[n] = kk
                    expected += kk * Qu + 0.5 * kk * kk * Quu
                    for i in range(4):
                        Vx[i] = Qx[i] + self._K[n, i] * (Quu * kk + Qu) + Qux[i] * kk
                        for j in range(4):
                            Vxx[i][j] = (Qxx[i][j] + self._K[n, i] * Quu * self._K[n, j]
                                         + self._K[n, i] * Qux[j] + Qux[i] * self._K[n, j])
                    for i in range(4):
                        for j in range(i):
                            Vxx[i][j] = 0.5 * (Vxx[i][j] + Vxx[j][i])
                            Vxx[j][i] = Vxx[i][j]
                else:
                    solved = True  # the backward pass went through
                    break
                if self.regularization >= MAX_REGULARIZATION:
                    break  # Q_uu stays negative: keep the plan, try again from the next state
                self.regularization = min(max(2.0 * self.regularization, 1e-4), MAX_REGULARIZATION)
            step_size = 1.0
            new_cost = INFINITY
            for attempt in range(line_search if solved else 0):
                new_cost = self._rollout(x, self._Xnew, self._Unew, self._X, self._U, step_size, True)
                if new_cost < cost:
                    break
                step_size *= 0.5
            if new_cost < cost:
                self._X[:, :] = self._Xnew
                self._U[:] = self._Unew
                cost = new_cost
                self.regularization = 0.5 * self.regularization if self.regularization > 1e-6 else 0.0
            else:
                self.regularization = min(max(4.0 * self.regularization, 1e-3), MAX_REGULARIZATION)
        return cost
