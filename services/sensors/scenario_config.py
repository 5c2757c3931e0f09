"""Choosing a simulated scenario: the configuration shared by every command that runs the
simulator (``skyfuse simulate``, ``skyfuse sensor``), and building the scenario from it."""

from __future__ import annotations

from pydantic import BaseModel, Field, field_validator
from skyfuse.services.runtime.config import ConfigError, parse_key_values


class ScenarioSelection(BaseModel):
    """Which scenario to simulate, with which seed, duration, targets and parameters."""

    scenario: str = Field("regional", description="Scenario name (skyfuse simulate --list)")
    seed: int = Field(1, ge=0, description="Random seed: the same seed gives the same data")
    duration: float | None = Field(None, gt=0, description="Duration in seconds (scenario default)")
    targets: int | None = Field(None, ge=0, description="Number of targets (scenario default)")
    param: list[str] = Field(
        default_factory=list, description="Scenario parameter overrides KEY=VALUE,KEY=VALUE"
    )

    @field_validator("param")
    @classmethod
    def _key_value(cls, v: list[str]) -> list[str]:
        for item in v:
            if "=" not in item or not item.split("=", 1)[0].strip():
                raise ValueError(f"param {item!r} is not KEY=VALUE")
        return v

    def build_scenario(self):
        """The :class:`fusion.sim.Scenario`, or a :class:`ConfigError` naming the bad
        parameter and the valid choices."""
        from skyfuse.fusion.sim import build_scenario

        try:
            return build_scenario(
                self.scenario,
                seed=self.seed,
                duration=self.duration,
                targets=self.targets,
                **parse_key_values(self.param),
            )
        except (ValueError, TypeError) as e:
            raise ConfigError(str(e)) from None
