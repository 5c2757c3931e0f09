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
RUN pip install . \
    && useradd --system --create-home --uid 10001 skyfuse \
    && mkdir -p /data /state /etc/skyfuse \
    && chown skyfuse /data /state \
    && chmod 700 /state

COPY deploy/*.toml /etc/skyfuse/
USER skyfuse
WORKDIR /data
# SIGTERM stops every skyfuse service within 5 s (compose stop_grace_period: 10s).
STOPSIGNAL SIGTERM
ENTRYPOINT ["skyfuse"]
CMD ["--help"]
