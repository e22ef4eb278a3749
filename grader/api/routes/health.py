"""Health: no token needed, so load balancers and compose healthchecks can call it."""

from fastapi import APIRouter
from fastapi.responses import Response
from prometheus_client import CONTENT_TYPE_LATEST, CollectorRegistry, generate_latest
from sqlalchemy import text

from grader.web.deps import SessionDep
from grader.core.db import new_session
from grader.ops import StatusCollector
from grader.core.schemas import Health

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health)
def health(session: SessionDep) -> Health:
    """Liveness and database reachability."""
    session.execute(text("SELECT 1"))
    return Health(status="ok", database=session.get_bind().dialect.name, version="1")


# At the root, where Prometheus scrapes by default; aggregate counts only, no token (like /v1/health).
metrics_router = APIRouter()


@metrics_router.get("/metrics", include_in_schema=False)
def metrics():
    """Prometheus metrics (text exposition format): queues, workers, case runs, failures, durations."""

    registry = CollectorRegistry()
    registry.register(StatusCollector(new_session))
    return Response(generate_latest(registry), media_type=CONTENT_TYPE_LATEST)
