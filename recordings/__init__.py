"""The sample recording(s) shipped as package data of ``skyfuse.recordings`` (see
:mod:`skyfuse.services.recording.sample`)."""
