"""Zenoh transport for the skyfuse services: configuration, sessions, publishers,
subscribers feeding one bounded FIFO inbox, liveliness and snapshot queries.

Rules this module enforces (stack-notes, Zenoh section):

* **Multicast scouting is off** unless asked for: a session only talks to the endpoints
  it is given (``--listen`` / ``--connect``), so tests and demos never send traffic off
  the machine.
* **Publishers use** ``CongestionControl.BLOCK``: the default DROP silently loses
  messages at saturation; plots, tracks and everything recorded must not be lost.
* **Sessions are always closed** (:func:`open_session` is a context manager): a process
  whose session still has a callback subscriber declared hangs at exit.
* Subscriber callbacks run on Zenoh's threads and only append ``(key, payload, time)``
  to a bounded FIFO (:class:`Inbox`); the service's main thread drains it with a timeout,
  so it can notice a stop request at any moment. A full inbox blocks the Zenoh thread,
  which with BLOCK publishers propagates back-pressure to the senders instead of losing
  samples.
* **Plots are published with Zenoh's advanced publishers** (:func:`declare_cached_publisher`,
  ``zenoh.ext``): each keeps its last ``cache`` samples and numbers them; a receiver
  subscribed with ``recover`` (:meth:`Inbox.subscribe`) notices a gap in the numbers (or,
  by the publisher's heartbeat, a missing last sample) and asks the publisher's cache for
  the missing samples, which then arrive in order; what the cache no longer holds is
  reported as missed (:meth:`Inbox.take_missed`). So a stalled receiver, or a link that
  Zenoh drops at its lease and opens again, loses nothing up to the cache depth. (A BLOCK
  publisher alone cannot prevent that loss: what is published while no link exists is
  routed nowhere.) The advanced publisher's extra keys are ``KEY/@adv/pub/…`` (its cache
  queryable and heartbeat), which the access policy must allow
  (:mod:`~skyfuse.services.runtime.security`).

Modes: ``peer`` (default; peers gossip, so a star of ``--connect`` to one listener is a
full mesh), ``client`` (connects to a router such as ``zenohd``; use with ``--connect``)
and ``router`` (a skyfuse process acting as the router).
"""

from __future__ import annotations

import contextlib
import json
import logging
import queue
import re
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import zenoh
from pydantic import BaseModel, Field, field_validator, model_validator
from skyfuse.services.runtime.config import ConfigError, add_model_arguments, build_config

log = logging.getLogger(__name__)

ENDPOINT_RE = re.compile(
    r"^(tcp|udp|tls|quic|ws|unixsock-stream)/(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.\-]+):(\d{1,5})"
    r"(#.*)?$"
)
ENV_PREFIX = "SKYFUSE_"
"""Environment variables ``SKYFUSE_MODE``, ``SKYFUSE_CONNECT``, ``SKYFUSE_LISTEN`` … set the
transport fields (comma-separated lists), below the command line in precedence."""


def check_endpoint(value: str) -> str:
    """Validate a Zenoh locator ``proto/host:port`` (e.g. ``tcp/127.0.0.1:7447``)."""
    m = ENDPOINT_RE.match(value)
    if not m:
        raise ValueError(
            f"endpoint {value!r} is not valid: use PROTO/HOST:PORT, e.g. tcp/127.0.0.1:7447"
        )
    port = int(m.group(3))
    if not 0 <= port <= 65535:
        raise ValueError(f"endpoint {value!r}: port {port} is outside 0..65535")
    return value


def endpoint_port(value: str) -> int:
    """The port number of an endpoint string."""
    return int(ENDPOINT_RE.match(check_endpoint(value)).group(3))


class TransportConfig(BaseModel):
    """How a service joins the Zenoh network."""

    mode: Literal["peer", "client", "router"] = Field(
        "peer", description="Zenoh mode: peer, client (needs --connect to a router) or router"
    )
    listen: list[str] = Field(
        default_factory=list, description="Endpoints to listen on, e.g. tcp/127.0.0.1:7447"
    )
    connect: list[str] = Field(
        default_factory=list, description="Endpoints to connect to, e.g. tcp/127.0.0.1:7447"
    )
    multicast: bool = Field(
        False, description="Enable multicast scouting (off: only the explicit endpoints)"
    )
    zenoh_config: Path | None = Field(
        None, description="A Zenoh JSON5 config file applied before the flags"
    )
    tls_root_ca: Path | None = Field(
        None, description="TLS: CA certificate (PEM) that signs every peer's certificate"
    )
    tls_cert: Path | None = Field(
        None,
        description="TLS: this process's certificate (PEM), shown when listening and "
        "connecting (mutual TLS)",
    )
    tls_key: Path | None = Field(None, description="TLS: this process's private key (PEM)")
    acl: Path | None = Field(
        None,
        description="Zenoh access-control policy to enforce (JSON5 object, as written by "
        "skyfuse certs; normally the router's)",
    )

    @field_validator("listen", "connect")
    @classmethod
    def _endpoints(cls, v: list[str]) -> list[str]:
        return [check_endpoint(e) for e in v]

    @model_validator(mode="after")
    def _tls_complete(self) -> TransportConfig:
        given = [self.tls_root_ca, self.tls_cert, self.tls_key]
        if any(v is not None for v in given) and not all(v is not None for v in given):
            raise ValueError(
                "tls_root_ca, tls_cert and tls_key go together (mutual TLS: each process "
                "shows its certificate and checks the others' against the CA)"
            )
        for name in ("tls_root_ca", "tls_cert", "tls_key", "acl"):
            path = getattr(self, name)
            if path is not None and not path.is_file():
                raise ValueError(f"{name}: {str(path)!r} is not a file")
        return self

    @property
    def tls(self) -> bool:
        return self.tls_root_ca is not None


TRANSPORT_FIELDS = tuple(TransportConfig.model_fields)


def zenoh_config(cfg: TransportConfig) -> zenoh.Config:
    """Build the ``zenoh.Config`` of ``cfg``: mode, endpoints, scouting."""
    if cfg.zenoh_config is not None:
        try:
            conf = zenoh.Config.from_file(str(cfg.zenoh_config))
        except Exception as e:  # zenoh raises its own error type for parse failures
            raise ConfigError(f"zenoh_config {str(cfg.zenoh_config)!r}: {e}") from None
    else:
        conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(cfg.mode))
    conf.insert_json5("scouting/multicast/enabled", "true" if cfg.multicast else "false")
    listen = cfg.listen or default_listen(cfg)
    if listen is not None:
        conf.insert_json5("listen/endpoints", json.dumps(listen))
        warn_exposed(listen, cfg.tls)
    if cfg.connect:
        conf.insert_json5("connect/endpoints", json.dumps(cfg.connect))
    if cfg.tls:
        _insert_tls(conf, cfg)
    if cfg.acl is not None:
        try:
            conf.insert_json5("access_control", cfg.acl.read_text())
        except Exception as e:  # zenoh's own error type for a bad policy
            raise ConfigError(f"acl {str(cfg.acl)!r}: {e}") from None
    if cfg.mode == "client" and not cfg.connect and not cfg.multicast:
        raise ConfigError(
            "mode client needs --connect (the router's endpoint) when multicast scouting is off"
        )
    return conf


def _insert_tls(conf: zenoh.Config, cfg: TransportConfig) -> None:
    """Mutual TLS: the same certificate when listening and connecting, peers checked
    against ``tls_root_ca``, a listener refuses peers without a certificate."""
    tls = {
        "root_ca_certificate": str(cfg.tls_root_ca),
        "listen_certificate": str(cfg.tls_cert),
        "listen_private_key": str(cfg.tls_key),
        "connect_certificate": str(cfg.tls_cert),
        "connect_private_key": str(cfg.tls_key),
        "enable_mtls": True,
        "verify_name_on_connect": True,
    }
    for name, value in tls.items():
        conf.insert_json5(f"transport/link/tls/{name}", json.dumps(value))


_LOOPBACK_HOSTS = ("127.", "[::1]", "localhost")


def warn_exposed(endpoints: list[str], tls: bool) -> list[str]:
    """Log a warning for every endpoint that listens beyond loopback without TLS (or on
    plain TCP next to a TLS configuration); return them."""
    exposed = []
    for ep in endpoints:
        m = ENDPOINT_RE.match(ep)
        proto, host = m.group(1), m.group(2)
        if proto in ("tls", "quic"):
            continue
        if tls or not host.startswith(_LOOPBACK_HOSTS):
            exposed.append(ep)
            log.warning(
                "listening on %s without TLS: anyone who can reach it can read and publish "
                "(see docs/deployment.md, secure deployment)",
                ep,
            )
    return exposed


LOOPBACK_PEER_LISTEN = ["tcp/127.0.0.1:0"]
"""Where a peer without ``--listen`` listens: loopback, a port chosen by the system. Peers
on this host still form a mesh (gossip tells them each other's locator), nothing off the
host can connect. (Zenoh's own default is ``tcp/[::]:0``: every interface.)"""
LOOPBACK_ROUTER_LISTEN = ["tcp/127.0.0.1:7447"]
"""Where a router without ``--listen`` listens (Zenoh's own default: ``tcp/[::]:7447``)."""


def default_listen(cfg: TransportConfig) -> list[str] | None:
    """The listen endpoints of a session given no ``--listen``: loopback only (peer,
    router; ``tls/`` with TLS), none for a client; ``None`` (keep the file's) with
    ``--zenoh-config``."""
    if cfg.zenoh_config is not None:
        return None
    if cfg.mode == "client":
        return []
    default = LOOPBACK_ROUTER_LISTEN if cfg.mode == "router" else LOOPBACK_PEER_LISTEN
    return [ep.replace("tcp/", "tls/", 1) for ep in default] if cfg.tls else default


@contextlib.contextmanager
def open_session(cfg: TransportConfig) -> Iterator[zenoh.Session]:
    """Open a Zenoh session for ``cfg`` and always close it on exit.

    Raises :class:`TransportError` if Zenoh refuses (e.g. the listen port is taken)."""
    conf = zenoh_config(cfg)
    try:
        session = zenoh.open(conf)
    except zenoh.ZError as e:
        raise TransportError(
            f"cannot open a Zenoh session (mode {cfg.mode}, listen {cfg.listen}, "
            f"connect {cfg.connect}): {e}"
        ) from None
    log.debug("zenoh session %s open (mode %s)", session.info.zid(), cfg.mode)
    try:
        yield session
    finally:
        try:
            session.close()
        except Exception as e:  # closing must never mask the real exit path
            log.warning("error while closing the zenoh session: %s", e)


class TransportError(RuntimeError):
    """The Zenoh session could not be opened or used."""


def declare_publisher(session: zenoh.Session, key: str, *, express: bool = False):
    """A publisher on ``key`` with ``CongestionControl.BLOCK`` (no silent loss) and the
    encoding of its payload (:func:`payload_encoding`)."""
    return session.declare_publisher(
        key,
        congestion_control=zenoh.CongestionControl.BLOCK,
        express=express,
        encoding=payload_encoding(key),
    )


PLOT_CACHE = 1000
"""Samples an advanced publisher keeps for recovery by default (plot batches per radar)."""
HEARTBEAT_S = 0.5
"""Period of an advanced publisher's heartbeat (the number of its last sample, sent when it
changed): a receiver that missed the last samples asks for them within this, s."""


def declare_cached_publisher(session: zenoh.Session, key: str, cache: int = PLOT_CACHE):
    """A publisher on ``key`` like :func:`declare_publisher` (BLOCK, the payload encoding)
    that also keeps its last ``cache`` samples for receivers that missed them, numbers its
    samples and sends a heartbeat (``zenoh.ext`` advanced publisher: module docstring)."""
    from zenoh.ext import CacheConfig, MissDetectionConfig, declare_advanced_publisher

    return declare_advanced_publisher(
        session,
        key,
        encoding=payload_encoding(key),
        congestion_control=zenoh.CongestionControl.BLOCK,
        cache=CacheConfig(max_samples=cache),
        sample_miss_detection=MissDetectionConfig(heartbeat=None, sporadic_heartbeat=HEARTBEAT_S),
    )


def payload_encoding(key: str) -> zenoh.Encoding:
    """``application/json;skyfuse.{Model}/{schema version}`` for a key of the v1 key
    space that carries a message (e.g. ``application/json;skyfuse.TrackBatch/1``), so
    generic Zenoh tools can decode it; ``zenoh/bytes`` for any other key."""
    from skyfuse.schemas import SCHEMA_VERSION, model_for_key

    try:
        model = model_for_key(key)
    except ValueError:
        return zenoh.Encoding.ZENOH_BYTES
    return zenoh.Encoding.APPLICATION_JSON.with_schema(f"skyfuse.{model.__name__}/{SCHEMA_VERSION}")


_STAMP = struct.Struct("<q")


def wall_stamp(ns: int | None = None) -> bytes:
    """An attachment carrying a wall-clock time in ns (default: now).

    Sensors stamp each PlotBatch with the wall-clock instant its sector sweep ended, so
    the fusion service can measure plot-to-track latency even when the plot times are
    simulated (fixed epoch, accelerated) rather than wall-clock times."""
    return _STAMP.pack(time.time_ns() if ns is None else int(ns))


def read_wall_stamp(data: bytes) -> int | None:
    """The time carried by :func:`wall_stamp`, or ``None`` for another attachment."""
    if len(data) != _STAMP.size:
        return None
    return _STAMP.unpack(data)[0]


@dataclass(slots=True)
class Received:
    """One received sample: what ``tag`` the subscription was given, the concrete key,
    the payload bytes, whether it is a PUT (liveliness: token appeared) or DELETE, the
    wall-clock receive time in ns and the sender's wall-clock stamp from the attachment
    (see :func:`wall_stamp`), if any."""

    tag: str
    key: str
    payload: bytes
    put: bool
    recv_ns: int
    sent_ns: int | None = None


class Inbox:
    """A bounded FIFO shared by several subscriptions; drained by one thread.

    Each subscription's callback runs on its own thread (zenoh-python's default
    ``indirect`` callbacks), so the FIFO keeps the order of one subscription's samples,
    not an order between subscriptions: a sample published first on one key can come
    after one published later on another (a site after the first plots,
    :mod:`~skyfuse.services.fusion.system_frame`). ``capacity`` bounds memory; when full,
    the delivering thread waits (back-pressure), except after :meth:`close`, when new
    samples are discarded so shutdown never blocks."""

    def __init__(self, capacity: int = 100_000) -> None:
        self._q: queue.Queue[Received] = queue.Queue(maxsize=capacity)
        self._closed = threading.Event()
        self._handles: list = []
        self.discarded = 0
        """Samples that arrived after :meth:`close` and were dropped."""
        self._sources: dict[tuple[str, int], str] = {}
        """Advanced publishers seen (zid, entity id) → the key of their last sample."""
        self._missed: dict[str, int] = {}
        self._missed_lock = threading.Lock()

    def _push(self, tag: str, sources: bool = False) -> Callable[[zenoh.Sample], None]:
        def callback(sample: zenoh.Sample) -> None:
            if sources:
                self._note_source(sample)
            att = sample.attachment
            item = Received(
                tag,
                str(sample.key_expr),
                sample.payload.to_bytes(),
                sample.kind == zenoh.SampleKind.PUT,
                time.time_ns(),
                read_wall_stamp(att.to_bytes()) if att is not None else None,
            )
            while not self._closed.is_set():
                try:
                    self._q.put(item, timeout=0.1)
                    return
                except queue.Full:
                    continue
            self.discarded += 1

        return callback

    def subscribe(
        self,
        session: zenoh.Session,
        key_expr: str,
        tag: str = "",
        *,
        remote_only: bool = False,
        recover: bool = False,
    ) -> None:
        """Subscribe to ``key_expr``; samples arrive tagged ``tag`` (default: the key).

        ``remote_only`` ignores this session's own publications: a service that publishes
        on keys it also subscribes to must use it, or a blocking ``put`` from the thread
        that drains a full inbox would wait for itself. ``recover``: an advanced
        subscriber (module docstring) that gets the samples it missed back from the
        publishers' caches and counts what they no longer hold (:meth:`take_missed`)."""
        origin = zenoh.Locality.REMOTE if remote_only else None
        if not recover:
            self._handles.append(
                session.declare_subscriber(
                    key_expr, self._push(tag or key_expr), allowed_origin=origin
                )
            )
            return
        from zenoh.ext import RecoveryConfig, declare_advanced_subscriber

        sub = declare_advanced_subscriber(
            session,
            key_expr,
            self._push(tag or key_expr, sources=True),
            allowed_origin=origin,
            recovery=RecoveryConfig(periodic_queries=None, heartbeat=True),
        )
        self._handles += [sub.sample_miss_listener(self._on_miss), sub]

    def _note_source(self, sample: zenoh.Sample) -> None:
        info = sample.source_info
        if info is None:
            return
        sid = (str(info.source_id.zid), int(info.source_id.eid))
        if sid not in self._sources and len(self._sources) >= MAX_SOURCES:
            self._sources.pop(next(iter(self._sources)))  # the oldest publisher seen
        self._sources[sid] = str(sample.key_expr)

    def _on_miss(self, miss) -> None:
        key = self._sources.get((str(miss.source.zid), int(miss.source.eid)), "")
        with self._missed_lock:
            if key not in self._missed and len(self._missed) >= MAX_SOURCES:
                key = ""  # an unknown or one too many source: counted together
            self._missed[key] = self._missed.get(key, 0) + int(miss.nb)

    def take_missed(self) -> dict[str, int]:
        """Samples reported missed since the last call, by key (``""``: a publisher not
        seen), and forget them."""
        with self._missed_lock:
            out, self._missed = self._missed, {}
        return out

    def subscribe_liveliness(
        self, session: zenoh.Session, key_expr: str, tag: str = "alive", history: bool = True
    ) -> None:
        """Follow liveliness tokens under ``key_expr``: PUT when one appears (and, with
        ``history``, for those already alive), DELETE when it goes away."""
        self._handles.append(
            session.liveliness().declare_subscriber(key_expr, self._push(tag), history=history)
        )

    def get(self, timeout: float | None = 0.1) -> Received | None:
        """The next sample, or ``None`` after ``timeout`` seconds."""
        try:
            return self._q.get(timeout=timeout)
        except queue.Empty:
            return None

    def drain(self, limit: int = 10_000) -> list[Received]:
        """Everything queued now (up to ``limit``), without waiting."""
        out = []
        while len(out) < limit:
            try:
                out.append(self._q.get_nowait())
            except queue.Empty:
                break
        return out

    def qsize(self) -> int:
        return self._q.qsize()

    def close(self) -> None:
        """Undeclare the subscriptions and stop accepting samples."""
        self._closed.set()
        for h in self._handles:
            with contextlib.suppress(Exception):
                h.undeclare()
        self._handles.clear()


MAX_SOURCES = 4096
"""Advanced publishers (and keys with misses) an :class:`Inbox` keeps track of, at most."""


def declare_liveliness(session: zenoh.Session, key: str):
    """Declare a liveliness token (undeclared when the session closes or the process dies)."""
    return session.liveliness().declare_token(key)


def alive_tokens(session: zenoh.Session, key_expr: str, timeout: float = 1.0) -> list[str]:
    """The keys of the liveliness tokens currently alive under ``key_expr``."""
    out = []
    for reply in session.liveliness().get(key_expr, timeout=timeout):
        if reply.ok is not None:
            out.append(str(reply.ok.key_expr))
    return sorted(set(out))


def query(session: zenoh.Session, key_expr: str, timeout: float = 2.0) -> list[tuple[str, bytes]]:
    """``get`` on a queryable: ``(key, payload)`` of every OK reply."""
    out = []
    for reply in session.get(key_expr, timeout=timeout):
        if reply.ok is not None:
            out.append((str(reply.ok.key_expr), reply.ok.payload.to_bytes()))
    return out


def service_alive_key(name: str) -> str:
    """Liveliness token of a running service: ``skyfuse/@v1/service/{name}/alive``."""
    from skyfuse.schemas import keys

    return keys.service_alive(name)


def wait_for_tokens(
    session: zenoh.Session,
    key_exprs: list[str],
    timeout: float,
    stop: threading.Event | None = None,
) -> list[str]:
    """Wait until a liveliness token is alive under every key expression; return the ones
    still missing after ``timeout`` seconds (empty list: all present).

    A liveliness subscriber per key (with history: the tokens already alive count) wakes
    the wait as soon as the last token appears, so several processes waiting for the same
    token start within milliseconds of each other (a poll every 50 ms plus a query each
    would spread them by ~0.1 s: seconds of data time for replays at ×50)."""
    present: set[str] = set()
    changed = threading.Event()

    def seen(k: str):
        def callback(sample) -> None:
            if sample.kind == zenoh.SampleKind.PUT:
                present.add(k)
                changed.set()

        return callback

    wanted = set(key_exprs)
    subs = [session.liveliness().declare_subscriber(k, seen(k), history=True) for k in wanted]
    try:
        deadline = time.monotonic() + timeout
        while not wanted <= present:
            left = deadline - time.monotonic()
            if left <= 0 or (stop is not None and stop.is_set()):
                break
            changed.wait(min(left, 0.05))
            changed.clear()
    finally:
        for sub in subs:
            with contextlib.suppress(Exception):
                sub.undeclare()
    return [k for k in key_exprs if k not in present]


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free on ``host`` right now (for tests and the demo)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def loopback_endpoint(port: int | None = None) -> str:
    """``tcp/127.0.0.1:PORT`` (a free port if none is given)."""
    return f"tcp/127.0.0.1:{port if port is not None else free_port()}"


def add_transport_arguments(parser) -> None:
    """Add ``--mode --listen --connect --multicast --zenoh-config`` to an argparse parser."""
    group = parser.add_argument_group("zenoh transport")
    add_model_arguments(group, TransportConfig)


def transport_config(args=None, *, toml_path=None, section: str | None = "transport"):
    """The :class:`TransportConfig` from defaults < TOML ``[transport]`` < ``SKYFUSE_*``
    environment < flags."""
    return build_config(
        TransportConfig, args, toml_path=toml_path, section=section, env_prefix=ENV_PREFIX
    )
