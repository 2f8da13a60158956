# hybrid-planner service image.
#   docker build -t hybrid-planner .
#   docker run --rm -p 8000:8000 hybrid-planner
#   docker run --rm -p 8000:8000 -e PLANNER_WORKERS=4 -e PLANNER_API_KEY=s3cret hybrid-planner
# Every setting is a PLANNER_* environment variable (docs/operations.md). Logs are JSON lines on
# stderr; Prometheus metrics at /metrics. `docker stop` sends SIGTERM and kills after 10 s:
# the image's drain and shutdown grace (PLANNER_DRAIN_S=2 + PLANNER_SHUTDOWN_TIMEOUT_S=6) fit
# in it; raise them together (`docker stop -t 40` with 5 + 30).
# Stage 1 installs the project and its pinned dependencies into a virtual environment and
# compiles the numba kernels once; stage 2 copies only that environment onto a slim base and
# runs it as an unprivileged user.
FROM python:3.11-slim AS build
# numba's compiled kernels go to one cache folder that the runtime stage reuses.
ENV PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_NO_CACHE_DIR=1 PYTHONDONTWRITEBYTECODE=1 \
    NUMBA_CACHE_DIR=/opt/numba-cache
WORKDIR /src
RUN python -m venv /opt/venv
COPY pyproject.toml constraints.txt README.md ./
COPY src ./src
COPY api ./api
RUN /opt/venv/bin/pip install --quiet -c constraints.txt . \
 && /opt/venv/bin/planner warm-up

FROM python:3.11-slim
RUN useradd --create-home --uid 10001 planner
COPY --from=build /opt/venv /opt/venv
COPY --from=build --chown=planner /opt/numba-cache /opt/numba-cache
ENV PATH=/opt/venv/bin:$PATH \
    PYTHONUNBUFFERED=1 \
    NUMBA_CACHE_DIR=/opt/numba-cache \
    PLANNER_HOST=0.0.0.0 \
    PLANNER_PORT=8000 \
    PLANNER_LOG_FORMAT=json \
    PLANNER_DRAIN_S=2 \
    PLANNER_SHUTDOWN_TIMEOUT_S=6
USER planner
WORKDIR /home/planner
EXPOSE 8000
STOPSIGNAL SIGTERM
HEALTHCHECK --interval=30s --timeout=5s --start-period=20s --retries=3 \
  CMD ["python", "-c", "import os, urllib.request; urllib.request.urlopen('http://127.0.0.1:%s/v1/health' % os.environ.get('PLANNER_PORT', '8000'), timeout=4)"]
# host and port come from PLANNER_HOST / PLANNER_PORT (0.0.0.0:8000 above), so that
# `docker run -e PLANNER_PORT=9000 ...` works like every other setting
CMD ["planner", "serve"]
