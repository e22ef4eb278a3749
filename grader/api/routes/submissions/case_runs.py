"""Case-run actions for a course's instructors: re-send a failed or stuck case run (the dashboard's resend)."""

from fastapi import APIRouter, status

from grader import dispatch
from grader.web.deps import CurrentUser, RowId, SessionDep
from grader.api.responses import errors
from grader.core.schemas import CaseRunPublic
from grader.services.reports.dashboard import resend_case_run

router = APIRouter(prefix="/case-runs", tags=["case runs"], responses=errors(401, 403, 404, 422))


@router.post("/{case_run_id}/resend", status_code=status.HTTP_202_ACCEPTED, response_model=CaseRunPublic,
             responses=errors(409, _409="The run is neither failed nor stuck, or its submission is being graded"))
def resend(case_run_id: RowId, session: SessionDep, user: CurrentUser):
    """Re-send a failed or stuck case run with a new attempt on its own backend's queue (instructors of its course).

    The state change is recorded as a `resent` event naming who resent it and keeping the previous error; a failed
    submission goes back to running, and a graded one keeps its grade in its history, superseded, and is graded
    again when its runs finish."""
    return resend_case_run(session=session, case_run_id=case_run_id, user=user, sender=dispatch)
