"""The registration key and payload: ``skyfuse/@v1/fusion/{id}/registration``
carries a ``RegistrationStatus``; the recorder keeps it and the MCAP reader decodes it."""

from __future__ import annotations

import time

import pytest
from pydantic import ValidationError
from skyfuse import schemas
from skyfuse.schemas import RegistrationStatus, Status, keys
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.recording.recorder import Recorder, RecorderConfig
from skyfuse.services.runtime.transport import Received

EST = {"radar_id": "LYVR", "reference": False, "azimuth": 0.0035, "azimuth_sigma": 1.5e-4,
       "range": 151.0, "range_sigma": 9.0, "range_gain": 2e-5, "range_gain_sigma": 7e-5,
       "time": 0.04, "time_sigma": 0.02, "pairs_used": 300, "pairs_rejected": 2}  # fmt: skip


def _status() -> RegistrationStatus:
    return RegistrationStatus(fusion_id="main", time=1, mode="on", radars=[EST])


def test_registration_key_payload_and_status_field():
    key = keys.fusion_registration("main")
    assert key == "skyfuse/@v1/fusion/main/registration"
    assert keys.parse(key) == keys.KeyInfo("registration", "main")
    assert schemas.model_for_key(key) is RegistrationStatus
    st = _status()
    assert RegistrationStatus.from_json_bytes(st.to_json_bytes()) == st
    s = Status(service="fusion", service_id="main", time=1, uptime_s=0.0, registration=st)
    assert Status.from_json_bytes(s.to_json_bytes()).registration == st
    with pytest.raises(ValidationError, match="azimuth_sigma"):
        RegistrationStatus(
            fusion_id="main", time=1, mode="on", radars=[{**EST, "azimuth_sigma": -1}]
        )
    with pytest.raises(ValidationError, match="mode"):
        RegistrationStatus(fusion_id="main", time=1, mode="maybe")


def test_recorder_records_the_registration_key(tmp_path):
    rec = Recorder(RecorderConfig(out=tmp_path / "r.mcap"))
    now = time.time_ns()
    item = Received("all", keys.fusion_registration("main"), _status().to_json_bytes(), True, now)
    assert rec.handle(item)
    rec.close()
    got = [r.message for r in iter_recording(rec.files[0])]
    assert got == [_status()]
