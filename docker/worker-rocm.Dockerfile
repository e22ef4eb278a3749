# ROCm worker image: torch built for HIP (torch.version.hip is set), Genesis asked for gs.amdgpu explicitly.
# Listens on the rocm queue only: a case that cannot get the GPU fails with a provenance error, never runs on CPU.
FROM rocm/pytorch:rocm6.4_ubuntu22.04_py3.11_pytorch_release_2.6.0
ENV PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 DATA_DIR=/data PYOPENGL_PLATFORM=egl
RUN useradd --create-home --uid 10001 --groups video,render grader && mkdir -p /data && chown grader:grader /data
# requirements/worker.lock without its torch: the image's ROCm torch stays; `--no-deps` installs exactly the lock.
COPY requirements/worker.lock /opt/requirements/worker.lock
RUN awk '/^torch==/ {skip = 1; next} /^[^ ]/ {skip = 0} !skip' /opt/requirements/worker.lock > /opt/requirements/rocm.lock \
    && pip install --require-hashes --no-deps -r /opt/requirements/rocm.lock \
    && python -c "import torch; assert torch.version.hip, 'not a ROCm build of torch'"
WORKDIR /app
COPY pyproject.toml README.md ./
COPY rubric rubric
COPY lessons lessons
COPY worker worker
COPY examples examples
COPY grader grader
RUN pip install --no-deps -e .
USER grader
HEALTHCHECK --interval=30s --timeout=20s --retries=3 --start-period=10m \
    CMD ["grader", "worker", "--queue", "rocm", "--healthy"]
CMD ["celery", "-A", "worker.celery_app", "worker", "-Q", "rocm", "-c", "1", "--pool", "prefork", \
     "-n", "rocm@%h", "--loglevel", "info"]
