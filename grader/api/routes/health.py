"""Health: no token needed, so load balancers and compose healthchecks can call it."""

from fastapi import APIRouter
from sqlalchemy import text

from grader.api.deps import SessionDep
from grader.schemas import Health

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health)
def health(session: SessionDep) -> Health:
    """Liveness and database reachability."""
    session.execute(text("SELECT 1"))
    return Health(status="ok", database=session.get_bind().dialect.name, version="1")
