"""`grader lti ...`: an operator's LTI 1.3 set-up on the service's own database: registering a platform for a course,
listing a course's registrations, the tool's signing keys (shown, or rotated), and an assignment's counted scores
sent to the LMS gradebooks."""

from __future__ import annotations

import json

import click


@click.group()
def lti() -> None:
    """LTI 1.3: platform registrations, the tool's keys, scores to the LMS (operators, on the service's database)."""


def _refusal(exc) -> click.ClickException:
    rules = "; ".join(f"{e['field']}: {e['rule']}" for e in exc.errors)
    return click.ClickException(exc.detail + (f" ({rules})" if rules else ""))


@lti.command()
@click.argument("course_name", metavar="COURSE")
@click.option("--issuer", required=True, help="The platform's issuer (iss), e.g. https://canvas.instructure.com")
@click.option("--client-id", required=True, help="The client id the platform gave this tool")
@click.option("--deployment-id", "deployment_ids", multiple=True, required=True,
              help="A deployment id the platform launches from (repeat for several)")
@click.option("--auth-login-url", required=True, help="The platform's OIDC authorization endpoint")
@click.option("--auth-token-url", required=True, help="The platform's OAuth2 token endpoint")
@click.option("--key-set-url", required=True, help="The platform's public keys (JWKS URL)")
def register(course_name: str, issuer: str, client_id: str, deployment_ids: tuple[str, ...], auth_login_url: str,
             auth_token_url: str, key_set_url: str) -> None:
    """Register a platform whose launches sign people into COURSE (created if new)."""
    # lazy: SQLAlchemy (~0.5 s) stays off `grader --help`; only the database commands load it
    from grader.core.db import new_session
    from grader.services.identity import accounts
    from grader.services.lti import launch as logic
    from grader.services.errors import DomainError

    with new_session() as session:
        course = accounts.get_or_create_course(session=session, name=course_name)
        try:
            row = logic.create_registration(session=session, course=course, issuer=issuer, client_id=client_id,
                                            deployment_ids=list(deployment_ids), auth_login_url=auth_login_url,
                                            auth_token_url=auth_token_url, key_set_url=key_set_url)
        except DomainError as exc:
            raise _refusal(exc) from None
        session.commit()
        click.echo(f"registration {row.id}: {row.issuer} client {row.client_id} -> course {course.name} "
                   f"(deployments: {', '.join(d.deployment_id for d in row.deployments)})")


@lti.command(name="list")
@click.argument("course_name", metavar="COURSE")
def list_registrations(course_name: str) -> None:
    """List COURSE's platform registrations."""
    # lazy: SQLAlchemy (~0.5 s) stays off `grader --help`; only the database commands load it
    from sqlalchemy import select

    from grader.core.db import new_session
    from grader.core.models import Course
    from grader.services.lti import launch as logic

    with new_session() as session:
        course = session.scalar(select(Course).where(Course.name == course_name))
        if course is None:
            raise click.ClickException(f"no course {course_name}")
        for row in logic.course_registrations(session=session, course=course):
            click.echo(f"{row.id}\t{row.issuer}\t{row.client_id}\t{','.join(d.deployment_id for d in row.deployments)}")


@lti.command()
@click.option("--rotate", is_flag=True, help="Make a new signing key; the old public key stays published a while")
def keys(rotate: bool) -> None:
    """Print the tool's public keys (its JWKS, also served at /lti/jwks); with --rotate, rotate first."""
    # lazy: SQLAlchemy (~0.5 s) stays off `grader --help`; only the database commands load it
    from grader.core.db import new_session
    from grader.services.lti import launch as logic

    with new_session() as session:
        if rotate:
            click.echo(f"new signing key {logic.rotate_key(session=session).kid}", err=True)
        jwks = logic.public_jwks(session=session)
        session.commit()
    click.echo(json.dumps(jwks, indent=2))


@lti.command()
@click.argument("assignment_id", type=int)
@click.option("--url", envvar="GRADER_URL", default="http://127.0.0.1:8000", show_default=True,
              help="The service's public URL, for the report link in each score's comment")
def scores(assignment_id: int, url: str) -> None:
    """Send ASSIGNMENT_ID's counted scores to the LMS gradebooks: only changed or failed ones go."""
    # lazy: SQLAlchemy (~0.5 s) stays off `grader --help`; only the database commands load it
    from grader.core.db import new_session
    from grader.core.models import Assignment
    from grader.services.lti import launch as logic

    with new_session() as session:
        assignment = session.get(Assignment, assignment_id)
        if assignment is None:
            raise click.ClickException(f"no assignment {assignment_id}")
        sent = logic.send_scores(session=session, assignment=assignment,
                                 report_url=url.rstrip("/") + "/submissions/{id}")
        session.commit()
    for row in sent:
        click.echo(f"{row.student}\t{row.context}\t{row.status}\t{'' if row.score is None else row.score}"
                   + (f"\t{row.error}" if row.error else ""))
    if any(row.status == "failed" for row in sent):
        raise click.ClickException("some scores were not sent; run again to retry them")
