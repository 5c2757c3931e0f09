"""How an ASTERIX input becomes plot batches: the options every command that reads ASTERIX
shares (``skyfuse track``, ``skyfuse eval``, ``skyfuse sensor --asterix/--asterix-udp``),
declared once so that a setting has one flag, one TOML key and one description
everywhere."""

from __future__ import annotations

from pydantic import BaseModel, Field


class AsterixReadOptions(BaseModel):
    """Sectors of radars without CAT034, the batch window of report sensors without
    update-cycle messages, and an empirical ADS-B σ."""

    sector_count: int = Field(
        16, ge=1, le=360, description="ASTERIX: fixed sectors per turn for radars without CAT034"
    )
    report_window: float = Field(
        1.0,
        ge=0.05,
        le=60,
        description="ASTERIX: batch window of report sensors without update-cycle messages "
        "(ADS-B), s",
    )
    adsb_sigma: float | None = Field(
        None,
        ge=0.01,
        le=10_000,
        description="ASTERIX: σ per axis of every ADS-B position, m (an empirical figure; default: "
        "the one its NACp/NUCp gives)",
    )
