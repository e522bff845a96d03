# kinoplan: the REST API (8000) and the 3D viewer (8080); the same image runs the Dask
# scheduler and workers of docker-compose.yml. Build: docker build -t kinoplan .
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PIP_ROOT_USER_ACTION=ignore

# numba's cache of the compiled kernels. numba uses a cache directory only where it may
# write (it checks), and the installed package's __pycache__ belongs to root: the kernels
# compiled there at build time were compiled again by each container's first requests and
# jobs. This directory belongs to the service's user instead, and every process of the
# image (API, compute workers, job steps, Dask workers) reads the kernels built into it.
ENV NUMBA_CACHE_DIR=/var/cache/kinoplan/numba

# Unprivileged user; /data (SQLite store of custom robots and jobs) belongs to it, so a new
# named volume mounted there starts with that owner.
RUN useradd --create-home --uid 10001 --shell /usr/sbin/nologin kinoplan \
    && mkdir /data \
    && chown kinoplan:kinoplan /data

# Only what the package needs to build and run.
WORKDIR /src
COPY pyproject.toml README.md ./
COPY app/ ./app/
COPY kinematics/ ./kinematics/
COPY kinoplan/ ./kinoplan/
COPY planning/ ./planning/
COPY web/ ./web/
RUN pip install --no-cache-dir ".[dask]"
# Every compiled kernel (kinematics, motion planner, sequencing: planning.warm) goes into the
# image, from the installed package (cd /), so no container compiles one again.
RUN cd / && python -m kinoplan warm-up \
    && chown -R kinoplan:kinoplan "$NUMBA_CACHE_DIR"

# Run from the installed package (as the Dask workers do), not from the source tree.
WORKDIR /home/kinoplan
USER kinoplan

ENV KINOPLAN_DATA_DIR=/data
VOLUME ["/data"]
EXPOSE 8000 8080

# No curl in slim images: the stdlib asks GET /health on the port the service listens on.
HEALTHCHECK --interval=30s --timeout=5s --start-period=20s --retries=3 \
    CMD ["python", "-c", "import os, sys, urllib.request; port = os.environ.get('KINOPLAN_PORT', '8000'); sys.exit(0 if urllib.request.urlopen(f'http://127.0.0.1:{port}/health', timeout=4).status == 200 else 1)"]

# Flags appended to `docker run IMAGE ...` go to the service, e.g. `--workers 4`.
ENTRYPOINT ["python", "-m", "kinoplan", "--host", "0.0.0.0"]
CMD []
