# skyfuse services image: `docker build -t skyfuse .`
# Every service runs the `skyfuse` command: sensor, fusion, record, replay, tracks, ...
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1

WORKDIR /opt/skyfuse
COPY pyproject.toml README.md ./
COPY schemas ./schemas
COPY fusion ./fusion
COPY services ./services
COPY recordings ./recordings
# The tracker's compiled (numba) kernels are compiled here, once, into a cache the
# runtime user owns (`skyfuse warmup`): site-packages is not writable by that user, and
# numba never reads a cache it cannot write, so it would otherwise compile them again
# (about 20 s) at every start of a fresh container.
ENV NUMBA_CACHE_DIR=/opt/skyfuse/numba-cache
RUN pip install . \
    && skyfuse warmup \
    && useradd --system --create-home --uid 10001 skyfuse \
    && mkdir -p /data /state /etc/skyfuse \
    && chown skyfuse /data /state \
    && chown -R skyfuse "$NUMBA_CACHE_DIR" \
    && chmod 700 /state

COPY deploy/*.toml /etc/skyfuse/
USER skyfuse
WORKDIR /data
# SIGTERM stops every skyfuse service within 5 s (compose stop_grace_period: 10s).
STOPSIGNAL SIGTERM
ENTRYPOINT ["skyfuse"]
CMD ["--help"]
