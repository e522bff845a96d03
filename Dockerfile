# kinoplan: the REST API (8000) and the 3D viewer (8080); the same image runs the Dask
# scheduler and workers of docker-compose.yml. Build: docker build -t kinoplan .
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PIP_ROOT_USER_ACTION=ignore

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
COPY planning/ ./planning/
COPY web/ ./web/
RUN pip install --no-cache-dir ".[dask]"
# The compiled kinematics kernels go into the image, so no container compiles them again.
RUN cd / && python -c "from kinematics.fast import warm_up; warm_up()"

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
ENTRYPOINT ["python", "-m", "app", "--host", "0.0.0.0"]
CMD []
