# API image: FastAPI + SQLAlchemy + Celery client. No Genesis, no torch: it starts in well under a second.
FROM python:3.11-slim
WORKDIR /app
ENV PYTHONUNBUFFERED=1 DATA_DIR=/data
COPY pyproject.toml README.md ./
COPY grader grader
COPY rubric rubric
COPY worker worker
COPY examples examples
# The API's own dependencies only; `--no-deps` keeps genesis-world and torch out of this image.
RUN pip install --no-cache-dir "fastapi>=0.110" "uvicorn>=0.29" "sqlalchemy>=2.0" "alembic>=1.13" \
        "psycopg2-binary>=2.9" "celery[redis]>=5.4" "redis>=5.0" "pydantic>=2.7" "pydantic-settings>=2.3" \
        "numpy>=2.0" "pyyaml>=6.0" "click>=8.1" "httpx>=0.27" "matplotlib>=3.8" "python-multipart>=0.0.9" \
    && pip install --no-cache-dir --no-deps -e .
EXPOSE 8000
HEALTHCHECK --interval=15s --timeout=5s --retries=5 \
    CMD python -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:8000/v1/health')"
# API_WORKERS processes under uvicorn's own supervisor (it restarts one that dies); docker-compose.yml sets 2.
CMD ["sh", "-c", "grader admin migrate && exec uvicorn grader.main:app --host 0.0.0.0 --port 8000 --workers ${API_WORKERS:-1}"]
