# ROCm worker image: torch built for HIP (torch.version.hip is set), Genesis asked for gs.amdgpu explicitly.
# Listens on the rocm queue only: a case that cannot get the GPU fails with a provenance error, never runs on CPU.
FROM rocm/pytorch:rocm6.4_ubuntu22.04_py3.11_pytorch_release_2.6.0
WORKDIR /app
ENV PYTHONUNBUFFERED=1 DATA_DIR=/data PYOPENGL_PLATFORM=egl
COPY pyproject.toml README.md ./
COPY grader grader
COPY rubric rubric
COPY worker worker
COPY examples examples
# Keep the image's ROCm torch: install the project without letting pip replace torch with a CPU/CUDA wheel.
RUN pip install --no-cache-dir genesis-world==1.3.3 "celery[redis]>=5.4" "redis>=5.0" "sqlalchemy>=2.0" \
        "alembic>=1.13" "psycopg2-binary>=2.9" "pydantic-settings>=2.3" "pyyaml>=6.0" "click>=8.1" "httpx>=0.27" \
        "matplotlib>=3.8" "fastapi>=0.110" \
    && pip install --no-cache-dir --no-deps -e . \
    && python -c "import torch; assert torch.version.hip, 'not a ROCm build of torch'"
HEALTHCHECK --interval=30s --timeout=20s --retries=3 \
    CMD celery -A worker.celery_app inspect ping -d "rocm@$HOSTNAME" --timeout 10 || exit 1
CMD ["celery", "-A", "worker.celery_app", "worker", "-Q", "rocm", "-c", "1", "--pool", "prefork", \
     "-n", "rocm@%h", "--loglevel", "info"]
