"""The roster from the LMS (LTI Names and Role Provisioning Services): a course's students as its LMS courses list
them, read one page at a time and written in short batches.

A roster may be large (an LMS course of thousands, a platform that lists every member it ever had), so nothing here
is bounded by the roster's size but by one page (settings.outbound_max_bytes of JSON) and one batch: each page is
read with no transaction open (a platform may take its time to answer, and no lock or pooled connection may wait
with it), its learners are written in batches of BATCH, each its own transaction of a few bulk statements, and the
page is let go before the next is asked for. Another request never waits longer than one batch for the database.
A course reads at most settings.lti_roster_max_members members (every entry of every page, all roles and statuses):
the page that would pass the cap is not stored, and the sync stops there.

A sync that stops (the cap, a page that could not be read) keeps the pages stored before it: whole pages, each
batch all or nothing, and says so in its Conflict; nobody is reported as dropped then (the rest of the roster was
not read). Syncing again, once the cause is fixed, completes it: a known learner is found by their LMS id, so nobody
is duplicated."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import requests
from pylti1p3.exception import LtiException
from pylti1p3.names_roles import NamesRolesProvisioningService
from sqlalchemy import insert, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader.core.models import Course, LtiContext, LtiIdentity, LtiRegistration, User, utcnow
from grader.core.settings import settings
from grader.core.states import Role
from grader.services.errors import Conflict
from grader.services.lti.launch import LEARNER_ROLES, RegistrationConf, _Connector, _user_name, failure_text

# Learners written per transaction: a few bulk statements of this many rows (SQLite held its one write lock for
# 30 ms with them, 50 ms at most, on a loaded 2-core machine).
BATCH = 500
# SQLite has one write lock, and a connection waiting for it (its busy handler, sqlite3_busy_timeout) sleeps between
# tries, up to 100 ms apart: the lock is left free at least this long between two batches, so that such a waiter
# finds it free (back to back, a sign-in during a 20,000-learner sync lost the lock to batch after batch for 0.3-1 s).
SQLITE_WRITE_GAP_S = 0.1


@dataclass(frozen=True)
class RosterSync:
    added: list[str]
    updated: list[str]
    dropped: list[str]  # LMS students no longer active there: reported, never deleted (their submissions stay)
    unchanged: int


@dataclass
class _Tally:
    """What a sync has read and stored so far."""

    members: int = 0  # entries read, every role and status: what the cap counts
    added: list[str] = field(default_factory=list)
    updated: list[str] = field(default_factory=list)
    unchanged: int = 0
    listed: set[tuple[int, str]] = field(default_factory=set)  # (registration id, LMS id) of each active learner
    wrote_at: float | None = None  # time.monotonic() when the last batch let the write lock go

    def wait_for_waiters(self, session: Session) -> None:
        """On SQLite, lets the write lock stay free for SQLITE_WRITE_GAP_S after the last batch before the next takes
        it (the gap is mostly spent reading the next batch anyway): a request waiting to write polls the lock at
        most that far apart, and would otherwise lose it to batch after batch."""
        if self.wrote_at is not None and session.get_bind().dialect.name == "sqlite":
            time.sleep(max(0.0, SQLITE_WRITE_GAP_S - (time.monotonic() - self.wrote_at)))

    def stored(self) -> str:
        """What a stopped sync kept, in the words of its Conflict."""
        synced = len(self.added) + len(self.updated) + self.unchanged
        if not synced:
            return "nothing was stored"
        return (f"{'the 1 learner' if synced == 1 else f'the {synced} learners'} of the pages before "
                f"{'was' if synced == 1 else 'were'} synced "
                f"({len(self.added)} added, {len(self.updated)} updated), nobody was reported as dropped")


def sync_roster(*, session: Session, course: Course) -> RosterSync:
    """The course's students as its LMS courses list them (every registration's context with a roster service):
    new ones are created, known ones updated (name, email), found by their LMS id so nobody is duplicated. Students
    an LMS lists as inactive or no longer lists are reported as dropped and kept. Staff are left alone.

    Commits: the caller's transaction is ended before the first page is asked for, and each batch of learners is
    committed as it is written (module docstring). A Conflict when no LMS course offered its roster (nothing
    changed), when a page could not be read or the roster passed settings.lti_roster_max_members (the pages before
    are kept, and the Conflict says so)."""
    contexts = list(session.scalars(select(LtiContext).join(LtiRegistration)
                                    .where(LtiRegistration.course_id == course.id,
                                           LtiContext.memberships_url.is_not(None)).order_by(LtiContext.id)))
    if not contexts:
        raise Conflict("no LMS course of this course offered its roster yet: launch the tool from the LMS first")
    conf = RegistrationConf(session)
    # Plain values and pylti1p3's registrations (the tool's signing key made on first use), read before any request.
    rosters = [(context.context_id, context.memberships_url, context.registration,
                conf.library_registration(context.registration)) for context in contexts]
    tally = _Tally()
    for name, url, registration, library_registration in rosters:
        for number, members in _pages(session, name, url, library_registration, tally):
            tally.members += len(members)
            if tally.members > settings.lti_roster_max_members:
                raise Conflict(f"the LMS roster of {name} lists more than {settings.lti_roster_max_members} "
                               "members, the most a course's roster sync reads (LTI_ROSTER_MAX_MEMBERS): stopped "
                               f"at its page {number}, of which nothing was stored; {tally.stored()}")
            learners = _active_learners(members, registration.id, tally)
            del members  # the page's entries go before its learners are written
            for start in range(0, len(learners), BATCH):
                _store(session, course.id, registration, learners[start:start + BATCH], tally)
    dropped = _dropped(session, {registration.id for _, _, registration, _ in rosters}, tally.listed)
    return RosterSync(added=tally.added, updated=tally.updated, dropped=dropped, unchanged=tally.unchanged)


def _pages(session: Session, name: str, url: str, registration, tally: _Tally) -> Iterator[tuple[int, list]]:
    """Each page's members of one LMS course's roster, in order, following the platform's `next` links (at most
    launch.MAX_PAGES, counted by the connector). The session's transaction is ended before each request."""
    service = NamesRolesProvisioningService(_Connector(registration), {"context_memberships_url": url})
    number, next_url = 0, url
    while next_url:
        session.commit()  # nothing written is pending here (each batch commits); this ends the reads' transaction
        number, page_url = number + 1, next_url
        try:
            members, next_url = service.get_members_page(page_url)
        except (LtiException, requests.RequestException, AttributeError, KeyError, TypeError, ValueError) as exc:
            raise Conflict(f"the LMS roster of {name} could not be read: {failure_text(exc)}; "
                           f"{tally.stored()}") from None
        if not isinstance(members, list):
            raise Conflict(f"the LMS roster of {name} could not be read: {page_url} answered members that are no "
                           f"list; {tally.stored()}")
        yield number, members


def _active_learners(members: list, registration_id: int, tally: _Tally) -> list[tuple[str, str | None, str | None]]:
    """The page's active learners not seen before in this sync, as (LMS id, name, email): a name only where one is
    given (1 to 128 characters kept), an email only where it looks like one. Each is added to `tally.listed`."""
    learners = []
    for member in members:
        if not isinstance(member, dict):
            continue
        sub, roles = member.get("user_id"), member.get("roles") or []
        roles = roles if isinstance(roles, list) else []
        if not isinstance(sub, str) or not 0 < len(sub) <= 255 or not any(r in LEARNER_ROLES for r in roles):
            continue
        if member.get("status", "Active") != "Active":
            continue  # inactive there: reported with the dropped at the end
        if (registration_id, sub) in tally.listed:
            continue  # listed twice (another page, another LMS course of the platform): synced once
        tally.listed.add((registration_id, sub))
        name, email = member.get("name"), member.get("email")
        name = name.strip()[:128] if isinstance(name, str) and name.strip() else None
        email = email if isinstance(email, str) and 0 < len(email) <= 254 and "@" in email else None
        learners.append((sub, name, email))
    return learners


def _store(session: Session, course_id: int, registration: LtiRegistration, learners: list, tally: _Tally) -> None:
    """One batch of learners in one transaction: the known ones read in one query (before the write lock is taken),
    the new ones inserted (users, then their LMS identities) and the changed ones updated in bulk, then committed. A
    learner another request created meanwhile (a launch, a second sync) makes the insert fail: the batch is rolled
    back and written again once, reading them anew."""
    for attempt in (1, 2):
        batch = _plan(session, course_id, registration, learners)
        tally.wait_for_waiters(session)
        try:
            _write(session, registration.id, batch)
            session.commit()
        except IntegrityError:
            session.rollback()
            if attempt == 2:
                raise
            continue
        finally:
            tally.wrote_at = time.monotonic()
        tally.added += [values["name"] for _, values in batch.new]
        tally.updated += batch.updated
        tally.unchanged += batch.unchanged
        return


@dataclass
class _Batch:
    """What one batch writes, as read before it writes anything."""

    new: list[tuple[str, dict]] = field(default_factory=list)  # (LMS id, the user's columns) of each new learner
    changes: list[dict] = field(default_factory=list)  # each known learner's changed columns, with the user's id
    updated: list[str] = field(default_factory=list)  # their user names
    unchanged: int = 0


def _plan(session: Session, course_id: int, registration: LtiRegistration, learners: list) -> _Batch:
    """The batch's learners sorted into new, changed and unchanged, from one query of the known ones (a read: in
    SQLite no lock is held after it, in PostgreSQL none that a writer waits for)."""
    known = {row.sub: row for row in session.execute(
        select(LtiIdentity.sub, User.id, User.name, User.role, User.full_name, User.email)
        .join(User, User.id == LtiIdentity.user_id)
        .where(LtiIdentity.registration_id == registration.id, LtiIdentity.sub.in_([s for s, _, _ in learners])))}
    batch = _Batch()
    for sub, name, email in learners:
        row = known.get(sub)
        if row is None:
            batch.new.append((sub, {"course_id": course_id, "name": _user_name(registration, sub),
                                    "role": Role.STUDENT.value, "full_name": name, "email": email}))
            continue
        after = (Role.STUDENT.value, name or row.full_name, email or row.email)
        if after == (row.role, row.full_name, row.email):
            batch.unchanged += 1
            continue
        batch.changes.append({"id": row.id, "role": after[0], "full_name": after[1], "email": after[2]})
        batch.updated.append(row.name)
    return batch


def _write(session: Session, registration_id: int, batch: _Batch) -> None:
    """The batch's statements, no commit: executemany inserts without RETURNING (SQLite would insert a row per
    statement to keep the order), the new users' ids read back by their names (unique in the course)."""
    if batch.new:
        now = utcnow()
        session.execute(insert(User.__table__), [values | {"created_at": now} for _, values in batch.new])
        names = [values["name"] for _, values in batch.new]
        course_id = batch.new[0][1]["course_id"]
        ids = dict(session.execute(select(User.name, User.id).where(User.course_id == course_id,
                                                                    User.name.in_(names))).all())
        session.execute(insert(LtiIdentity.__table__), [{"registration_id": registration_id, "sub": sub,
                                                         "user_id": ids[values["name"]], "created_at": now}
                                                        for sub, values in batch.new])
    if batch.changes:
        session.execute(update(User), batch.changes)


def _dropped(session: Session, registrations: set[int], listed: set[tuple[int, str]]) -> list[str]:
    """The students of these registrations' LMS identities whom no roster listed as active, by name: read in
    slices, never the whole table at once."""
    rows = session.execute(select(LtiIdentity.registration_id, LtiIdentity.sub, User.name)
                           .join(User, User.id == LtiIdentity.user_id)
                           .where(LtiIdentity.registration_id.in_(registrations), User.role == Role.STUDENT.value)
                           .execution_options(yield_per=2_000))
    return sorted(name for registration_id, sub, name in rows if (registration_id, sub) not in listed)
