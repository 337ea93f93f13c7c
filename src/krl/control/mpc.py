"""Convex MPC of the ground-reaction forces (thesis Section 4.2.6.1; the public convex-MPC expert).

Model: the robot as a single rigid body with massless legs (centroidal dynamics), linearised about
level posture, written in the *heading frame* H (world axes turned by the current yaw, origin at the
centre of mass), so the dynamics matrix does not depend on yaw. State (13):

    x = [roll, pitch, yaw, p_x, p_y, p_z, ω_x, ω_y, ω_z, v_x, v_y, v_z, g]

    Θ̇ = ω,   ṗ = v,   ω̇ = I_H⁻¹ Σ r_i × f_i,   v̇ = Σ f_i / m + (0, 0, g),   ġ = 0

with g = -9.81 m/s² carried as a state so the model is linear (not affine). The continuous A is
nilpotent (A³ = 0), so the exact zero-order-hold discretisation over dt is closed-form:

    A_d = I + A dt + A² dt²/2,    B_d = (I dt + A dt²/2 + A² dt³/6) B = Φ B.

Over the horizon (10 × 25 ms) the foot positions r_i and the inertia are held at their current values,
so with A_d constant the condensed prediction ``X = A_qp x0 + B_qp U`` needs only the constant powers
``A_d^k`` and ``A_d^k Φ`` (precomputed) times the per-call B. Forces of feet that the contact schedule
puts in swing at a horizon step are eliminated from the QP (fixed at zero) instead of constrained, so
the QP has 3 × (number of stance foot-steps) variables (≤ 120). Stance forces satisfy a friction
pyramid and normal-force bounds. The QP is solved by DAQP, a dense dual active-set solver
(``docs/mpc.md`` has the measurements behind that choice).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import daqp
import numpy as np

from krl.robots.a1.constants import NUM_LEGS, STANDING_INERTIA, TOTAL_MASS

GRAVITY: float = -9.81
"""Gravitational acceleration along world z [m/s²]."""

_INF = 1e30  # DAQP's "no bound"

STATE_SIZE: int = 13
FORCE_SIZE: int = 3 * NUM_LEGS

DEFAULT_WEIGHTS: tuple[float, ...] = (5.0, 5.0, 0.2, 0.0, 0.0, 10.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0)
"""State tracking weights of the public convex-MPC expert: (roll, pitch, yaw, p, ω, v, g)."""


class MPCError(RuntimeError):
    """The MPC's QP could not be solved (infeasible or numerical failure)."""


@dataclass(frozen=True)
class MPCParams:
    """Parameters of the convex MPC."""

    horizon: int = 10
    """Number of prediction steps."""
    dt: float = 0.025
    """Prediction step [s]."""
    weights: tuple[float, ...] = DEFAULT_WEIGHTS
    """Diagonal state weights, one per state (13)."""
    force_weight: float = 1e-6
    """Weight of the squared ground-reaction forces [1/N²]. The public expert's 1e-5 makes the plan
    sag toward the end of the horizon and the first-step support exceed the weight by 20 % (docs/mpc.md)."""
    friction: float = 0.6
    """Friction-pyramid coefficient used by the planner (below the ground's 1.0, for margin)."""
    min_normal_force: float = 0.0
    """Lower bound of a stance foot's normal force [N]."""
    max_normal_force: float = 150.0
    """Upper bound of a stance foot's normal force [N]."""
    mass: float = TOTAL_MASS
    """Mass of the single rigid body [kg]."""
    inertia: tuple[float, ...] = tuple(STANDING_INERTIA.ravel())
    """Body-frame inertia about the centre of mass, row-major 3x3 [kg·m²]; default: the whole A1 in
    its standing pose (``constants.STANDING_INERTIA``)."""

    def __post_init__(self) -> None:
        if self.horizon < 1:
            raise ValueError(f"MPC horizon must be >= 1, got {self.horizon}")
        if not self.dt > 0:
            raise ValueError(f"MPC dt must be > 0 s, got {self.dt}")
        if len(self.weights) != STATE_SIZE or min(self.weights) < 0:
            raise ValueError(f"MPC weights must be 13 non-negative numbers, got {self.weights}")
        if not self.force_weight > 0:
            raise ValueError(f"MPC force_weight must be > 0, got {self.force_weight}")
        if not self.friction > 0:
            raise ValueError(f"MPC friction must be > 0, got {self.friction}")
        if not 0 <= self.min_normal_force < self.max_normal_force:
            raise ValueError(
                "MPC normal-force bounds must satisfy 0 <= min < max, got "
                f"({self.min_normal_force}, {self.max_normal_force})"
            )
        if not self.mass > 0 or len(self.inertia) != 9:
            raise ValueError("MPC mass must be > 0 and inertia a row-major 3x3 (9 numbers)")


@dataclass
class MPCSolution:
    """Result of one MPC update."""

    forces: np.ndarray
    """Ground-reaction forces on the robot for the first step, heading frame [N]. Shape: (4, 3)."""
    plan: np.ndarray
    """All planned forces, heading frame [N]. Shape: (horizon, 4, 3)."""
    num_variables: int
    """QP size after eliminating swing feet."""
    iterations: int = 0
    """Active-set iterations DAQP used."""
    extra: dict = field(default_factory=dict)


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix: ``skew(a) @ b == cross(a, b)``. Shape: (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


class ConvexMPC:
    """The condensed convex MPC. Build once; call :meth:`solve` every control step."""

    def __init__(self, params: MPCParams | None = None) -> None:
        self.params = p = params or MPCParams()
        n, h = STATE_SIZE, p.horizon
        a = np.zeros((n, n))
        a[0:3, 6:9] = np.eye(3)
        a[3:6, 9:12] = np.eye(3)
        a[11, 12] = 1.0
        a2 = a @ a
        dt = p.dt
        self.a_d = np.eye(n) + a * dt + a2 * dt**2 / 2
        self.phi = np.eye(n) * dt + a * dt**2 / 2 + a2 * dt**3 / 6
        powers = [np.eye(n)]
        for _ in range(h):
            powers.append(self.a_d @ powers[-1])
        # only weighted states enter the cost: drop the zero-weight rows once, here
        self._rows = np.flatnonzero(np.asarray(p.weights) > 0)
        sqrt_w = np.sqrt(np.asarray(p.weights)[self._rows])
        self._sqrt_w = np.tile(sqrt_w, h)  # (h * nw,)
        # X_k = A_d^k x0 + sum_{j<k} A_d^(k-1-j) Φ B u_j  for k = 1..h
        self._a_qp = np.concatenate([powers[k][self._rows] for k in range(1, h + 1)]) * self._sqrt_w[:, None]
        self._p_stack = np.stack([(powers[m] @ self.phi)[self._rows] for m in range(h)])  # (h, nw, n)
        nw = len(self._rows)
        # block (k, j) of B_qp is block m = k - j of the stack, zero (index h) above the diagonal
        k_idx, j_idx = np.meshgrid(np.arange(h), np.arange(h), indexing="ij")
        self._toeplitz = np.where(j_idx <= k_idx, k_idx - j_idx, h)
        self._nw = nw
        self._inertia_body = np.asarray(p.inertia, dtype=float).reshape(3, 3)
        self._inv_mass = 1.0 / p.mass
        # friction pyramid rows for one foot (fx, fy, fz): fx - μ fz <= 0, fx + μ fz >= 0, same for fy
        mu = p.friction
        pyramid = np.array([[1.0, 0.0, -mu], [1.0, 0.0, mu], [0.0, 1.0, -mu], [0.0, 1.0, mu]])
        max_feet = h * NUM_LEGS
        self._pyramids = np.kron(np.eye(max_feet), pyramid)  # block diagonal, sliced per call
        self._upper_bounds = np.tile([_INF, _INF, p.max_normal_force], max_feet)
        self._lower_bounds = np.tile([-_INF, -_INF, p.min_normal_force], max_feet)
        self._upper_general = np.tile([0.0, _INF, 0.0, _INF], max_feet)
        self._lower_general = np.tile([-_INF, 0.0, -_INF, 0.0], max_feet)

    def input_matrix(self, foot_rel_com: np.ndarray, body_to_heading: np.ndarray) -> np.ndarray:
        """Continuous input matrix B [per N]. Shape: (13, 12).

        Args:
            foot_rel_com: foot positions minus the centre of mass, heading frame [m]. Shape: (4, 3).
            body_to_heading: rotation of the trunk into the heading frame (roll and pitch). Shape: (3, 3).
        """
        inertia = body_to_heading @ self._inertia_body @ body_to_heading.T
        inv_inertia = np.linalg.inv(inertia)
        b = np.zeros((STATE_SIZE, FORCE_SIZE))
        b[6:9] = (inv_inertia @ skew(foot_rel_com)).transpose(1, 0, 2).reshape(3, FORCE_SIZE)
        b[9:12] = np.tile(np.eye(3) * self._inv_mass, NUM_LEGS)
        return b

    def solve(
        self,
        x0: np.ndarray,
        reference: np.ndarray,
        foot_rel_com: np.ndarray,
        body_to_heading: np.ndarray,
        contacts: np.ndarray,
    ) -> MPCSolution:
        """Plan the ground-reaction forces.

        Args:
            x0: current state (see module docstring), heading frame. Shape: (13,).
            reference: desired states at prediction steps 1..horizon. Shape: (horizon, 13).
            foot_rel_com: foot positions minus centre of mass, heading frame [m]. Shape: (4, 3).
            body_to_heading: trunk orientation relative to the heading frame. Shape: (3, 3).
            contacts: planned stance of each foot at prediction steps 0..horizon-1. Shape: (horizon, 4).

        Raises:
            MPCError: the QP failed (the message names DAQP's exit flag).
        """
        p = self.params
        h, nw = p.horizon, self._nw
        b = self.input_matrix(foot_rel_com, body_to_heading)
        blocks = np.concatenate((self._p_stack @ b, np.zeros((1, nw, FORCE_SIZE))))  # (h+1, nw, 12)
        b_qp = blocks[self._toeplitz].transpose(0, 2, 1, 3).reshape(h * nw, h * FORCE_SIZE)
        keep_feet = np.asarray(contacts, dtype=bool).reshape(h * NUM_LEGS)
        keep = np.repeat(keep_feet, 3)
        plan = np.zeros((h, NUM_LEGS, 3))
        n_feet = int(keep_feet.sum())
        if n_feet == 0:
            return MPCSolution(forces=plan[0].copy(), plan=plan, num_variables=0)
        b_w = b_qp[:, keep] * self._sqrt_w[:, None]
        error = self._a_qp @ x0 - (reference[:, self._rows].reshape(-1) * self._sqrt_w)
        hessian = b_w.T @ b_w
        hessian[np.diag_indices_from(hessian)] += p.force_weight
        gradient = b_w.T @ error
        n = 3 * n_feet
        constraints = self._pyramids[: 4 * n_feet, :n]
        upper = np.concatenate((self._upper_bounds[:n], self._upper_general[: 4 * n_feet]))
        lower = np.concatenate((self._lower_bounds[:n], self._lower_general[: 4 * n_feet]))
        sense = np.zeros(len(upper), dtype=np.int32)
        solution, _, exitflag, info = daqp.solve(hessian, gradient, constraints, upper, lower, sense)
        if exitflag < 1:
            raise MPCError(f"MPC QP failed: DAQP exit flag {exitflag} with {n} variables")
        plan.reshape(h * NUM_LEGS, 3)[keep_feet] = np.asarray(solution).reshape(n_feet, 3)
        return MPCSolution(
            forces=plan[0].copy(), plan=plan, num_variables=n, iterations=int(info.get("iterations", 0))
        )
