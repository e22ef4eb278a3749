# CPU worker image: Genesis on the CPU torch wheel, installed from requirements/worker.lock (pyproject.toml's
# dependencies and its `worker` extra, pinned with hashes); listens on the cpu and grade queues.
# PYTHON_IMAGE: any Debian-like image with python3.11 and its venv module (docker/api.Dockerfile).
# TORCH_INDEX_URL: where pip finds the locked CPU torch wheel (torch==...+cpu); empty to use only the `wheels` context.
# The `wheels` build context: a folder of wheels pip may take first (this project's machines keep the torch wheel on
# disk: `--build-context wheels=/opt/wheels`); by default the empty stage below.
ARG PYTHON_IMAGE=python:3.11-slim

FROM scratch AS wheels

FROM ${PYTHON_IMAGE}
ARG TORCH_INDEX_URL=https://download.pytorch.org/whl/cpu
ENV PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 \
    VIRTUAL_ENV=/opt/venv PATH=/opt/venv/bin:$PATH DATA_DIR=/data PYOPENGL_PLATFORM=egl
# EGL/Mesa for headless rendering (the lesson's camera frames); the X client libraries pyglet loads when Genesis
# imports it (without libXrender a case dies with "'NoneType' object has no attribute 'XRenderFindVisualFormat'").
RUN apt-get update && apt-get install -y --no-install-recommends libegl1 libgl1 libgles2 libglib2.0-0 libglu1-mesa \
        libx11-6 libxrender1 libxext6 libxi6 libxxf86vm1 libxfixes3 libxcursor1 libxinerama1 libxrandr2 \
    && rm -rf /var/lib/apt/lists/* \
    && python3 -m venv /opt/venv && useradd --create-home --uid 10001 grader \
    && mkdir -p /data && chown grader:grader /data
COPY requirements/worker.lock /opt/requirements/worker.lock
RUN --mount=type=bind,from=wheels,target=/wheels \
    pip install --require-hashes --no-deps --find-links /wheels \
        ${TORCH_INDEX_URL:+--extra-index-url "$TORCH_INDEX_URL"} -r /opt/requirements/worker.lock \
    && pip check
WORKDIR /app
COPY pyproject.toml README.md ./
COPY rubric rubric
COPY lessons lessons
COPY worker worker
COPY examples examples
COPY grader grader
RUN pip install --no-deps -e .
USER grader
# Genesis compiles the lesson's kernels on its first cases (minutes): done once here, for the scene structures a
# worker's warm case process loads when it starts (every installed lesson's warm_up_cases:
# worker.warm_process.warm_up_cases), so that a new worker takes its first case warm. The compose file's genesis-cache
# volume starts as a copy of this cache. The build host's cache mount keeps the kernels between builds, so a rebuild
# after a source change only loads them. A build that cannot list them fails (an empty list would build no kernels).
RUN --mount=type=cache,id=l03-grader-genesis-kernels,target=/home/grader/.kernels,uid=10001,gid=10001 \
    cases=$(python -c "from worker.warm_process import warm_up_cases; print(*(name for name, _ in warm_up_cases()))") \
    && test -n "$cases" \
    && for case in $cases; do \
        grader case show "$case" > /tmp/case.json \
        && XDG_CACHE_HOME=/home/grader/.kernels grader case run /tmp/case.json --out "/tmp/warm-$case" --mode isolated \
        || exit 1; \
    done \
    && mkdir -p /home/grader/.cache && cp -a /home/grader/.kernels/. /home/grader/.cache/ \
    && rm -rf /tmp/warm-* /tmp/case.json
# Answers a ping by its node name (cpu-grade@HOST, below) and takes cases, every slot warm (grader.ops.worker_health).
HEALTHCHECK --interval=30s --timeout=20s --retries=3 --start-period=10m CMD ["grader", "worker", "--healthy"]
CMD ["celery", "-A", "worker.celery_app", "worker", "-Q", "cpu,grade", "-c", "1", "--pool", "prefork", \
     "-n", "cpu-grade@%h", "--loglevel", "info"]
