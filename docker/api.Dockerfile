# API image (also the reconciler's): FastAPI + SQLAlchemy + the Celery client, installed from requirements/api.lock,
# pyproject.toml's [project] dependencies pinned with hashes. No Genesis, no torch: it starts in a few seconds.
# PYTHON_IMAGE: any Debian-like image with python3.11 and its venv module. The default is the official image; the
# container test (tests/integration/test_containers.py) passes one made from Debian's own packages (docker/ci/).
ARG PYTHON_IMAGE=python:3.11-slim
FROM ${PYTHON_IMAGE}
ENV PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 \
    VIRTUAL_ENV=/opt/venv PATH=/opt/venv/bin:$PATH DATA_DIR=/data
RUN python3 -m venv /opt/venv && useradd --create-home --uid 10001 grader \
    && mkdir -p /data && chown grader:grader /data
# Dependencies first (their own layer: rebuilt only when the lock changes), then the project without them.
COPY requirements/api.lock /opt/requirements/api.lock
RUN pip install --require-hashes --no-deps -r /opt/requirements/api.lock \
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
EXPOSE 8000
HEALTHCHECK --interval=15s --timeout=5s --retries=5 \
    CMD python -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:8000/v1/health')"
# API_WORKERS processes under uvicorn's own supervisor (it restarts one that dies); docker-compose.yml sets 2.
# --no-proxy-headers: uvicorn would otherwise trust X-Forwarded-For from 127.0.0.1 (a process in the container); the app
# trusts only FORWARDED_ALLOW_IPS, the proxy in front of it (grader.web.admission.TrustedProxies).
CMD ["sh", "-c", "grader admin migrate && exec uvicorn grader.main:app --host 0.0.0.0 --port 8000 --no-proxy-headers --workers ${API_WORKERS:-1}"]
