"""What an :class:`~mjsound.sim.simulator.AudioSimulator` reports: the event log, event counts
and per-step timings since its last reset (a mixin of the simulator: it reads its step
driver's log and counters and its contact reader)."""

from __future__ import annotations

__all__ = ["SimulatorReports"]


class SimulatorReports:
    """Event log, counts and timings of :class:`~mjsound.sim.simulator.AudioSimulator`."""

    @property
    def event_log(self) -> list:
        """The first ``keep_events`` events since the last reset, in order:
        ``(time [s], kind, geom1, geom2, value)``, kind ``"impact"`` (value: impulse [N s]) or
        ``"slide"`` / ``"roll"`` (one per pair and physics step; value: speed [m/s])."""
        return self.driver.event_log

    @property
    def n_impacts(self) -> int:
        """Impact events since the last reset (``events["impact"]``, without building the dict)."""
        return self.reader.n_impacts_made - self.driver.impacts_base

    @property
    def events(self) -> dict:
        """Counts since the last reset: ``impact`` events, and ``slide`` / ``roll`` pair-steps
        (a pair sliding or rolling for one physics step counts once)."""
        s = self.reader.sustained_steps - self.driver.sustained_base
        return {"impact": self.n_impacts, "slide": int(s[0]), "roll": int(s[1])}

    @property
    def impacts(self):
        """:class:`ImpactRecord` list (predicted vs MuJoCo impulse) of the reader."""
        return self.reader.impacts

    def stats(self) -> dict:
        """Counts and timings so far."""
        return {
            "steps": self.steps,
            "samples": self.samples,
            "events": dict(self.events),
            "contact_us_per_step": 1e6 * self.seconds_contacts / max(self.steps, 1),
            "synth_us_per_step": 1e6 * self.seconds_synth / max(self.steps, 1),
            "clamped": self.reader.n_clamped,
        }
