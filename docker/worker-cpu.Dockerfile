# CPU worker image: Genesis on the CPU torch wheel; listens on the cpu and grade queues.
FROM python:3.11-slim
WORKDIR /app
ENV PYTHONUNBUFFERED=1 DATA_DIR=/data PYOPENGL_PLATFORM=egl
# EGL/Mesa for headless rendering (the lesson's camera frames).
RUN apt-get update && apt-get install -y --no-install-recommends libegl1 libgl1 libgles2 libglib2.0-0 \
    && rm -rf /var/lib/apt/lists/*
RUN pip install --no-cache-dir torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu
COPY pyproject.toml README.md ./
COPY grader grader
COPY rubric rubric
COPY worker worker
COPY examples examples
RUN pip install --no-cache-dir -e .
# Warm the Genesis kernel cache at build time (~100 s once); the named volume keeps it across restarts.
RUN grader case show N1 > /tmp/n1.json && grader case run /tmp/n1.json --out /tmp/warm --mode isolated && rm -rf /tmp/warm
HEALTHCHECK --interval=30s --timeout=20s --retries=3 \
    CMD celery -A worker.celery_app inspect ping -d "cpu-grade@$HOSTNAME" --timeout 10 || exit 1
CMD ["celery", "-A", "worker.celery_app", "worker", "-Q", "cpu,grade", "-c", "1", "--pool", "prefork", \
     "-n", "cpu-grade@%h", "--loglevel", "info"]
