"""The domain errors services raise; the web layer turns each into an answer in one place (grader.web.errors).

    DomainError
    ├── NotFound       no such thing, or the caller may not know it exists          (API 404, the not-found page)
    ├── Forbidden      the caller's role may not do this in their course             (API 403)
    ├── Conflict       the thing is not in a state that allows it now                (API 409)
    └── Invalid        bad input: each error names the field and the rule            (API 422)
        └── Refused    a submission its assignment does not take now, or a request past its quota; Retry-After
                       where waiting helps (API 409/429)
"""

from __future__ import annotations


class DomainError(Exception):
    """A refusal a person should read: `detail` says what and why; `errors` name fields and rules where they apply.

    `reason` and `facts` (optional) say the same as data, for a page to put in its reader's words: a key naming the
    rule (`opens`, `closed`...) and its values as they are (titles, datetimes, counts), never formatted."""

    def __init__(self, detail: str, errors: list[dict[str, str]] | None = None, *, reason: str | None = None,
                 facts: dict | None = None):
        super().__init__(detail)
        self.detail, self.errors = detail, errors or []
        self.reason, self.facts = reason, dict(facts or {})


class NotFound(DomainError):
    pass


class Forbidden(DomainError):
    pass


class Conflict(DomainError):
    pass


class Invalid(DomainError):
    pass


class Refused(Invalid):
    """A submission the assignment does not take now; `field` and `rule` say why (with the time that applies).
    `retry_after_s` is set when waiting helps (the hourly limit): the API answers 429 with Retry-After."""

    def __init__(self, field: str, rule: str, retry_after_s: int | None = None, *, detail: str = "submission refused",
                 reason: str | None = None, facts: dict | None = None):
        super().__init__(detail, [{"field": field, "rule": rule}], reason=reason, facts=facts)
        self.args = (rule,)
        self.field, self.rule, self.retry_after_s = field, rule, retry_after_s


def field_errors(lines: list[str], prefix: str = "") -> list[dict[str, str]]:
    """'field.path: rule' lines (rubric.describe_errors) as [{field, rule}], each field under `prefix`."""
    out = []
    for line in lines:
        field, sep, rule = line.partition(": ")
        field, rule = (field, rule) if sep else ("", line)
        out.append({"field": ".".join(p for p in (prefix, field) if p), "rule": rule})
    return out
