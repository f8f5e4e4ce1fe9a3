"""A wheel's slip curve: the force along and across a tyre grows with its slip, then saturates.

Why this exists: a friction force that saturates at a centimetre a second of slip (a knife-edge)
leaves a four-wheeled skid-steer free to turn about any point between its axles, since every
wheel then scrubs at full μ2·N and the front and rear forces cancel wherever the centre lies.
A tyre's side force grows with its slip angle over several degrees before it saturates, so the
front and rear forces balance only where the slip angles do: about the middle of the loads.

Each direction of the contact (ODE's friction pyramid, as SDF's μ and μ2 mean) is linear, then
saturating (docs/robot.md, "How the tug turns: a tyre with a slip curve"):

    F = −clip(k · u, −μ·N, μ·N)        k = min(C · N / V, N / (g · dt) · STEP_MARGIN)

where u is the contact's slip velocity in that direction, N the wheel's load, V the wheel's
rolling speed (the larger of the ground's speed along the wheel and the wheel surface's), so that
u / V is the slip ratio along and the tangent of the slip angle across; C the stiffness per unit
load and slip (`STIFFNESS_ALONG`, `STIFFNESS_ACROSS`). Where the SDF states `<ode><slip1>` or
`<slip2>` (ODE's force-dependent slip, in m/s per N, the parameter gz-sim's WheelSlip system
sets), k = 1 / slip instead. Either k is bounded by the stiffest damper an explicit step of dt
integrates without ringing: the wheel's share of the mass (N / g) over the step, times a margin.
Below the speed where C · N / V reaches that bound (about 0.5 m/s along, 1.5 cm/s across at the
1 ms step), the tyre is that bound: a stiff damper that holds the robot still on held wheels.
"""

from __future__ import annotations

from dataclasses import dataclass

from simbot.description.model import Friction

G = 9.81
"""m/s²: the wheel's share of the mass is its load over g."""

STIFFNESS_ALONG = 40.0
"""Longitudinal slip stiffness, newtons per newton of load per unit slip ratio: μ (0.9) is reached
at 2.3 % of slip. The stiffest the 1 ms step integrates at walking speed (0.5 m/s)."""

STIFFNESS_ACROSS = 1.2
"""Cornering stiffness, newtons per newton of load per radian of slip angle: μ2 (0.25) is reached
at 12° of slip angle. A turn of radius R about the middle asks atan(0.58 / R) of the tug's wheels:
11° at 3 m, so the side force still grows with the slip angle there, and the loads, not the knife
edge, place the turn's centre."""

STEP_MARGIN = 0.8
"""Fraction of the explicit step's stability bound (k · dt / m = 1 damps a slip in one step)."""


@dataclass(frozen=True)
class Tyre:
    """One wheel's friction along (μ, along fdir1) and across (μ2), and how each grows with slip."""

    mu: float
    mu2: float
    stiffness_along: float = STIFFNESS_ALONG
    stiffness_across: float = STIFFNESS_ACROSS
    slip1: float = 0.0
    """SDF's force-dependent slip along (m/s per N); 0, SDF's default, leaves the stiffness to C."""
    slip2: float = 0.0
    """The same across."""

    @staticmethod
    def of(friction: Friction) -> Tyre:
        """The tyre of a wheel's SDF friction, with the default stiffness where it states no slip."""
        return Tyre(friction.mu, friction.mu2, slip1=friction.slip1, slip2=friction.slip2)

    def forces(
        self, slip_along: float, slip_across: float, rolling: float, load: float, step: float
    ) -> tuple[float, float]:
        """The friction force along and across on the wheel (newtons, opposing the slip velocities,
        m/s) at a rolling speed (m/s), a load (N) and an explicit step (s)."""
        bound = load * STEP_MARGIN / (G * step)
        along = _stiffness(self.slip1, self.stiffness_along, load, rolling, bound)
        across = _stiffness(self.slip2, self.stiffness_across, load, rolling, bound)
        limit1, limit2 = self.mu * load, self.mu2 * load
        return (
            -max(-limit1, min(limit1, along * slip_along)),
            -max(-limit2, min(limit2, across * slip_across)),
        )


def _stiffness(slip: float, stiffness: float, load: float, rolling: float, bound: float) -> float:
    """N·s/m of one direction: SDF's 1 / slip where stated, else C · N / V; at most `bound`."""
    if slip > 0.0:
        return min(1.0 / slip, bound)
    if stiffness * load >= bound * rolling:
        return bound
    return stiffness * load / rolling
