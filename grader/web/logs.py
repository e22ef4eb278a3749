"""What the server's access log may hold: never a sign-in link's secret. Installed on the `uvicorn.access` logger by
grader.main, so whatever runs the app (`uvicorn grader.main:app`, the image's command, --workers, --reload) writes
`/sign-in/link/[secret]` in place of the secret, which signs a student in once: anyone who reads the log (an
operator, a log shipper, a backup) must not be able to use a link that was not used yet."""

from __future__ import annotations

import logging
import re

# The secret is one path segment; it ends at the next '/', the query or the end (as uvicorn writes the path).
LINK_SECRET = re.compile(r"(/sign-in/link/)[^/?#\s\"]+")
REDACTED = r"\1[secret]"
ACCESS_LOGGER = "uvicorn.access"


def redact(text: str) -> str:
    return LINK_SECRET.sub(REDACTED, text)


class RedactSecrets(logging.Filter):
    """Rewrites each record's arguments (uvicorn's access record: client, method, path, version, status) and message
    so that no link secret reaches any handler or formatter."""

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple):
            record.args = tuple(redact(a) if isinstance(a, str) else a for a in record.args)
        if isinstance(record.msg, str):
            record.msg = redact(record.msg)
        return True


_FILTER = RedactSecrets()


def install() -> None:
    """On the access logger itself (a filter there sees every record logged to it, whichever handlers a log config
    gives it later); adding it twice is a no-op."""
    logging.getLogger(ACCESS_LOGGER).addFilter(_FILTER)
