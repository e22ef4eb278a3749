"""A worker takes no case until its case slots are warm: its case queues are held back until every slot's warm case
process has loaded the kernels and built the lesson's scenes, then consumed; meanwhile it says so in the broker's
store (grader.core.warmth), which /metrics, `grader status` and the progress page read.

The pieces, in the order they run:
- `hold` (celeryd_after_setup, the main process, -Q applied, before the pool forks): the case queues (one per
  backend) leave the set the consumer starts on, the grade queue stays; a shared array gets one flag per slot.
- `slot_warm` (in each pool process, from its slot's warm-up thread, worker.slot.start_slot): sets its flag.
- `WarmGate` (a consumer bootstep, on the consumer's own timer, so in its event loop): once every flag is set, it
  starts consuming the held queues and keeps how long the warm-up took; it renews the worker's record meanwhile.
Messages that arrive meanwhile stay in the broker, for a warm worker or for this one once warm: none waits in a cold
slot. A pool process replaced later (one died) warms its new case process while the worker goes on consuming.
"""

from __future__ import annotations

import multiprocessing
import time

from billiard.process import current_process
from celery import bootsteps
from celery.utils.log import get_logger

from grader.core import warmth
from grader.core.states import Backend, values

log = get_logger(__name__)  # under Celery's logger: the worker's log shows it (the root logger is not hijacked)

TICK_S = 0.25
OPENED = "case slots warm"  # the log line's words when the case queues open (tools.harness.processes waits on them)

_gate: dict = {}  # this worker's: name, queues, held, started_at, flags (a shared array, one per slot), warm_s


def hold(*, name: str, app, slots: int) -> None:
    """Take the case queues out of what the consumer starts on; one warm flag per slot, shared with the pool."""
    queues = sorted(app.amqp.queues.consume_from)
    held = [q for q in queues if q in values(Backend)]  # the case queues, one per backend (worker.celery_app)
    if held:
        app.amqp.queues.deselect(held)
    _gate.update(name=name, queues=tuple(queues), held=held, started_at=time.time(),
                 flags=multiprocessing.Array("b", max(1, slots)), warm_s=None if held else 0.0, renewed=0.0)


def slot_warm(line: dict) -> None:
    """Called in a pool process when its slot is warm (its warm-up line, or nothing to warm up)."""
    flags = _gate.get("flags")
    if flags is None:  # not under a gated worker (a solo test run)
        return
    with flags.get_lock():
        flags[current_process().index % len(flags)] = 1
    if not line.get("ok", True):
        log.warning("slot %d: its warm-up failed (see the lines above); the first case will show why",
                    current_process().index)


def slot_cold() -> None:
    """Called in a pool process as it starts: its slot warms again (a pool process replaced after one died)."""
    flags = _gate.get("flags")
    if flags is not None:
        with flags.get_lock():
            flags[current_process().index % len(flags)] = 0


def state() -> warmth.WorkerWarmth | None:
    if "flags" not in _gate:
        return None
    flags = _gate["flags"]
    with flags.get_lock():
        warm = sum(flags[:])
    return warmth.WorkerWarmth(name=_gate["name"], queues=_gate["queues"], slots=len(flags), warm=warm,
                               started_at=_gate["started_at"], warm_s=_gate["warm_s"])


def _renew(now: float, *, force: bool = False) -> None:
    if not force and now - _gate["renewed"] < warmth.RENEW_S:
        return
    _gate["renewed"] = now
    try:
        warmth.record(state())
    except Exception:  # noqa: BLE001 - a broker hiccup must not stop the consumer; the next renewal tries again
        log.exception("could not record this worker's warm-up state")


def forget() -> None:
    """The worker stops: its record goes at once."""
    if "name" in _gate:
        try:
            warmth.forget(_gate["name"])
        except Exception:  # noqa: BLE001 - it lapses on its own after warmth.RECORD_TTL_S
            log.exception("could not drop this worker's warm-up state")


class WarmGate(bootsteps.StartStopStep):
    """Consumes the held case queues once every slot is warm; renews the worker's record."""

    requires = ("celery.worker.consumer.tasks:Tasks",)

    def __init__(self, c, **kwargs):
        self.tref = None
        super().__init__(c, **kwargs)

    def start(self, c):
        if "flags" not in _gate:
            return
        if _gate["warm_s"] is None:  # logged here: the worker's logging is set up by now
            log.info("holding %s until %d case slots are warm", ", ".join(_gate["held"]), len(_gate["flags"]))
        self.tick(c)
        self.tref = c.timer.call_repeatedly(TICK_S, self.tick, (c,), priority=10)

    def stop(self, c):
        if self.tref is not None:
            self.tref.cancel()
            self.tref = None

    shutdown = stop

    def tick(self, c) -> None:
        now = time.time()
        current = state()
        if _gate["warm_s"] is None and current.warm == current.slots:
            _gate["warm_s"] = now - _gate["started_at"]
            for queue in _gate["held"]:
                c.add_task_queue(queue)
            log.info("all %d %s after %.1f s: consuming %s", current.slots, OPENED, _gate["warm_s"],
                     ", ".join(_gate["held"]))
            try:
                warmth.record_warm_up(_gate["warm_s"])
            except Exception:  # noqa: BLE001 - as in _renew
                log.exception("could not record the warm-up's duration")
            _renew(now, force=True)
            return
        _renew(now)
