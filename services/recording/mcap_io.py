"""MCAP recordings: one channel per key expression (the topic is the Zenoh key), JSON
messages with the pydantic model's JSON Schema, so Foxglove and the plain ``mcap``
reader can open them.

Files are chunked (zstd) and always carry a metadata record and message indexes, which
``pymcap-cli doctor`` requires (stack-notes). A file whose writer was killed has no
summary; :func:`iter_recording` then reads the complete chunks linearly and reports the
truncation instead of failing.

**Memory of a long recording.** The summary at the end of an MCAP file lists one chunk
index per chunk (where it is, its time range, the offsets of its message indexes), so a
writer must keep them until it finishes the file. ``mcap``'s Writer keeps each as a
Python object, ≈ 1 KB with 8 channels: a recorder that closes 17 chunks a second (a
2,000 plots/s soak with its track feed) grew by ≈ 1 MB a minute from them alone.
:class:`SpilledChunkIndexes` keeps them serialised (the summary's own bytes) in an
anonymous temporary file instead, beside the recording: constant memory, the same file
(byte for byte). The message indexes themselves are written after each chunk and never
kept.
"""

from __future__ import annotations

import functools
import json
import logging
import os
import struct
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.data_stream import RecordBuilder
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap.records import ChunkIndex
from mcap.writer import CompressionType, IndexType, Writer
from pydantic import ValidationError
from skyfuse import schemas
from skyfuse.schemas.base import WireModel

log = logging.getLogger(__name__)

SCHEMA_PREFIX = "skyfuse."
MCAP_MAGIC = b"\x89MCAP0\r\n"
"""The first 8 bytes of every MCAP file (MCAP specification, "Magic")."""


class NotMcapError(ValueError):
    """The file is not an MCAP recording; the message names the file and its first bytes."""


def check_mcap(path: str | Path) -> Path:
    """``path`` if it is a readable file starting with the MCAP magic, else raise
    ``FileNotFoundError`` (missing) or :class:`NotMcapError` (another kind of file)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    with open(path, "rb") as f:
        head = f.read(len(MCAP_MAGIC))
    if head[:5] != MCAP_MAGIC[:5]:
        kind = "an empty file" if not head else f"a file starting with {head!r}"
        raise NotMcapError(f"{path}: not an MCAP recording ({kind}; MCAP starts {MCAP_MAGIC!r})")
    return path


@functools.cache
def json_schema_bytes(model: type[WireModel]) -> bytes:
    """The model's JSON Schema, as stored in MCAP schema records (computed once per model)."""
    return json.dumps(model.model_json_schema(), separators=(",", ":")).encode()


class SpilledChunkIndexes:
    """The chunk indexes of an MCAP writer, serialised to an anonymous temporary file as
    they come (module docstring): what ``mcap``'s Writer needs of its list of them —
    :meth:`append` one, and iterate them once at ``finish()``, where each item writes
    itself into the summary (here one item writes all the serialised records, in order).

    ``directory``: where the temporary file lives (``None``: the system's temporary
    directory); it has no name, so nothing is left behind, even after ``kill -9``."""

    def __init__(self, directory: str | Path | None = None) -> None:
        self._file = tempfile.TemporaryFile(dir=directory)
        self.count = 0
        self.bytes = 0

    def append(self, index: ChunkIndex) -> None:
        builder = RecordBuilder()
        index.write(builder)
        data = builder.end()
        self._file.write(data)
        self.count += 1
        self.bytes += len(data)

    def __iter__(self):
        self._file.flush()
        self._file.seek(0)
        yield _SerialisedRecords(self._file.read())
        self._file.seek(0, os.SEEK_END)

    def close(self) -> None:
        self._file.close()


@dataclass
class _SerialisedRecords:
    data: bytes

    def write(self, builder: RecordBuilder) -> None:
        builder.write(self.data)


_CHUNK_INDEXES = "_Writer__chunk_indices"
"""The list of chunk indexes inside ``mcap.writer.Writer`` (mcap 1.2 – 1.6)."""


def spill_chunk_indexes(writer: Writer, directory=None) -> SpilledChunkIndexes | None:
    """Make ``writer`` keep its chunk indexes in a :class:`SpilledChunkIndexes`; ``None``
    (and a warning) if this ``mcap`` keeps them otherwise: they then stay in memory."""
    if type(getattr(writer, _CHUNK_INDEXES, None)) is not list or getattr(writer, _CHUNK_INDEXES):
        log.warning("mcap %s: chunk indexes kept in memory (no list to replace)", _mcap_version())
        return None
    spilled = SpilledChunkIndexes(directory)
    setattr(writer, _CHUNK_INDEXES, spilled)
    return spilled


def _mcap_version() -> str:
    from importlib.metadata import version

    return version("mcap")


class RecordingWriter:
    """Write skyfuse messages to an MCAP file, one channel per topic.

    ``metadata`` is stored as the ``skyfuse`` metadata record (command, scenario, seed…).
    Use as a context manager, or call :meth:`close`. The chunk indexes are kept on disk
    until the summary is written (:func:`spill_chunk_indexes`; ``spill_dir``: where,
    by default beside the recording, else the system's temporary directory).
    """

    def __init__(
        self,
        path: str | Path | IO[bytes],
        *,
        metadata: dict[str, str] | None = None,
        chunk_size: int = 1 << 20,
        compression: CompressionType = CompressionType.ZSTD,
        spill_dir: str | Path | None = None,
    ) -> None:
        self.path = path if isinstance(path, (str, Path)) else None
        self._file = open(path, "wb") if isinstance(path, (str, Path)) else path
        self._writer = Writer(
            self._file,
            chunk_size=chunk_size,
            compression=compression,
            index_types=IndexType.CHUNK | IndexType.MESSAGE | IndexType.METADATA,
        )
        if spill_dir is None and isinstance(getattr(self._file, "name", None), (str, Path)):
            spill_dir = Path(self._file.name).parent
        self.chunk_indexes = spill_chunk_indexes(self._writer, spill_dir)
        self._writer.start(profile="", library="skyfuse")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self.messages = 0
        self.bytes = 0
        self._writer.add_metadata("skyfuse", {k: str(v) for k, v in (metadata or {}).items()})
        self._closed = False

    def channel_for(
        self,
        topic: str,
        *,
        schema_name: str,
        schema_data: bytes,
        schema_encoding: str = "jsonschema",
        message_encoding: str = "json",
    ) -> int:
        """Register (once) and return the channel id of ``topic``."""
        cid = self._channels.get(topic)
        if cid is not None:
            return cid
        sid = self._schemas.get(schema_name)
        if sid is None:
            sid = self._writer.register_schema(schema_name, schema_encoding, schema_data)
            self._schemas[schema_name] = sid
        cid = self._writer.register_channel(topic, message_encoding, sid)
        self._channels[topic] = cid
        return cid

    def write(
        self,
        topic: str,
        message: WireModel | bytes,
        log_time: int,
        *,
        publish_time: int | None = None,
        model: type[WireModel] | None = None,
    ) -> None:
        """Write one message (a model, or its JSON bytes) at ``log_time`` (ns)."""
        if model is None:
            if isinstance(message, WireModel):
                model = type(message)
            else:
                model = schemas.model_for_key(topic)
        data = message.to_json_bytes() if isinstance(message, WireModel) else bytes(message)
        cid = self.channel_for(
            topic, schema_name=SCHEMA_PREFIX + model.__name__, schema_data=json_schema_bytes(model)
        )
        self.write_raw(cid, data, log_time, publish_time=publish_time)

    def write_raw(
        self, channel_id: int, data: bytes, log_time: int, *, publish_time: int | None = None
    ) -> None:
        seq = self._sequence.get(channel_id, 0)
        self._sequence[channel_id] = seq + 1
        self._writer.add_message(
            channel_id=channel_id,
            log_time=int(log_time),
            publish_time=int(log_time if publish_time is None else publish_time),
            data=data,
            sequence=seq,
        )
        self.messages += 1
        self.bytes += len(data)

    def flush(self) -> None:
        """Close the chunk in progress and flush it to the file, so a process killed after
        this loses nothing written before it (costs compression ratio if done often)."""
        if not self._closed:
            self._writer.flush()

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self._writer.add_metadata(name, {k: str(v) for k, v in data.items()})

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._writer.finish()
        if self.chunk_indexes is not None:
            self.chunk_indexes.close()
        if self.path is not None:
            self._file.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


@dataclass
class RecordedMessage:
    topic: str
    log_time: int
    publish_time: int
    data: bytes
    message: WireModel | None = None


@dataclass
class ReadStats:
    """What :func:`iter_recording` met: messages read, undecodable ones by reason, and
    whether the file ended without a summary (a killed writer)."""

    messages: int = 0
    rejected: dict[str, int] = field(default_factory=dict)
    truncated: bool = False
    errors: list[str] = field(default_factory=list)

    def reject(self, reason: str, detail: str) -> None:
        self.rejected[reason] = self.rejected.get(reason, 0) + 1
        if len(self.errors) < 20:
            self.errors.append(detail)


def iter_recording(
    path: str | Path,
    topics: Iterable[str] | None = None,
    *,
    decode: bool = True,
    stats: ReadStats | None = None,
) -> Iterator[RecordedMessage]:
    """Yield the messages of a recording in log-time order.

    With ``decode`` each skyfuse topic's payload is validated into its model; a message
    that fails is counted in ``stats.rejected`` (with the reason) and skipped, never
    fatal. Topics outside the skyfuse key space are yielded undecoded."""
    stats = stats if stats is not None else ReadStats()
    topic_list = list(topics) if topics is not None else None
    with open(path, "rb") as f:
        try:
            reader = make_reader(f)
            summary = reader.get_summary()
        except (McapError, struct.error, ValueError) as e:
            summary = None
            log.warning("%s: no readable summary (%s); reading chunks linearly", path, e)
        if summary is not None and summary.chunk_indexes:
            source = reader.iter_messages(topics=topic_list, log_time_order=True)
        else:
            stats.truncated = True
            f.seek(0)
            source = NonSeekingReader(f).iter_messages(topics=topic_list, log_time_order=False)
        try:
            for _schema, channel, msg in source:
                rec = RecordedMessage(channel.topic, msg.log_time, msg.publish_time, msg.data)
                if decode and channel.message_encoding == "json":
                    try:
                        model = schemas.model_for_key(channel.topic)
                    except ValueError:
                        model = None
                    if model is not None:
                        try:
                            rec.message = model.from_json_bytes(msg.data)
                        except ValidationError as e:
                            stats.reject(
                                f"invalid {model.__name__}",
                                f"{channel.topic} @ {msg.log_time}: {e.errors()[0]['msg']}",
                            )
                            continue
                stats.messages += 1
                yield rec
        except (McapError, EOFError, ValueError, struct.error) as e:
            stats.truncated = True
            stats.errors.append(f"recording ends early: {e}")
            log.warning("%s ends early (%s): kept %d messages", path, e, stats.messages)


def read_metadata(path: str | Path) -> dict[str, dict[str, str]]:
    """All metadata records of a recording, by name."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        try:
            return {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        except McapError:
            return {}
