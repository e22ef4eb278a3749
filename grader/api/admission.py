"""How many requests the API serves at once: settings.api_threads threads for sync handlers and dependencies, and as
many requests admitted, so every admitted request finds a database connection (grader.core.db sizes the pool)."""

from __future__ import annotations

from contextlib import asynccontextmanager

import anyio
import anyio.to_thread


@asynccontextmanager
async def lifespan(app, *, threads: int):
    """Size this event loop's thread pool (anyio's default limiter belongs to the running loop)."""
    anyio.to_thread.current_default_thread_limiter().total_tokens = threads
    yield


class InFlightLimit:
    """Admit at most `limit` HTTP requests into the app at once; later ones wait here, holding neither a thread nor a
    database connection, instead of taking a thread and then waiting on a pool whose connections are held by
    requests that wait for a thread."""

    def __init__(self, app, limit: int):
        self.app = app
        self.limit = limit
        self._slots: anyio.Semaphore | None = None

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if self._slots is None:  # created on first use, inside the serving event loop
            self._slots = anyio.Semaphore(self.limit)
        async with self._slots:
            await self.app(scope, receive, send)
