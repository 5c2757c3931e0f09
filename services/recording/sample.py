"""The sample recording shipped with skyfuse: ``regional-demo.mcap`` (a ``skyfuse demo``
run of the ``regional`` scenario: radar sites, plot batches, truth, fused tracks), under
2 MB. Installed as package data of ``skyfuse.recordings`` (the repository's
``recordings/`` folder), so ``skyfuse replay --sample`` / ``skyfuse track --sample``
find it after a plain ``pip install``."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

SAMPLE_NAME = "regional-demo.mcap"


def chosen_recording(file: Path | None, sample: bool) -> Path:
    """The recording a command was given: ``file`` or, with ``sample``, the installed
    sample; ``ValueError`` unless exactly one of them is given, ``FileNotFoundError``
    when the sample is not installed."""
    if sample == (file is not None):
        raise ValueError("give a recording FILE or --sample (one of the two)")
    return sample_recording() if sample else Path(file)


def sample_recording() -> Path:
    """The path of the installed sample recording (``FileNotFoundError`` if absent)."""
    try:
        path = Path(str(resources.files("skyfuse.recordings") / SAMPLE_NAME))
    except ModuleNotFoundError:  # a source tree without the package mapping
        path = Path(__file__).resolve().parents[2] / "recordings" / SAMPLE_NAME
    if not path.is_file():
        raise FileNotFoundError(f"the sample recording {SAMPLE_NAME} is not installed ({path})")
    return path
