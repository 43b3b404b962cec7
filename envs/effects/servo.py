"""Servo candidate effect: the arm does not execute the smallest lateral corrections (a deadband / play)."""

from __future__ import annotations

from drillgym.envs.effects.base import Effect, EffectHost, Param


class ServoDeadband(Effect):
    """Lost motion of lateral corrections: the servo-held tip moves across the drill axis only by more than a band.

    Per lateral task axis (x, y) the held tip position ``h`` follows the servo target ``t`` as a play of
    width b: ``h ← clip(h, t − b/2, t + b/2)``. A target that turns back moves the tip only after it has
    crossed the band, so a correction smaller than b is not executed at all and a larger one arrives
    b/2 short. The feed along the drill axis is untouched (a monotonic motion loses nothing but a
    constant b/2). Physically: the lost motion of six harmonic-drive joints (a few arc-minutes of
    hysteresis and torsional play each, 0.05–0.3 mm at the tip of a 0.5 m reach) and the servo's position
    deadband for sub-millimetre streamed corrections. The encoders follow the held tip (the servo's own
    deadband), so the RTDE TCP sees what was executed.
    """

    name = "servo_deadband"
    summary = "lateral corrections pass a play of width b: small ones are lost, larger ones arrive b/2 short"
    params = (Param("band_m", 0.0, 5e-4, 0.0, "width of the play across the drill axis (m)"),)
    channels = frozenset({"force", "torque", "tracker", "q", "tcp"})
    channels_before_contact = frozenset({"tracker", "q", "tcp"})

    def attach(self, env: EffectHost) -> None:
        """No held position yet: the first target is taken as it is."""
        self.held: list[float] | None = None

    def delay_target(self, t_s: float, target: tuple[float, float, float]) -> tuple[float, float, float]:
        """The target with its lateral components passed through the play (m, task frame)."""
        half = 0.5 * self.values["band_m"]
        if half <= 0.0:
            return target
        if self.held is None:
            self.held = [target[0], target[1]]
        for i in (0, 1):
            self.held[i] = min(max(self.held[i], target[i] - half), target[i] + half)
        return self.held[0], self.held[1], target[2]
