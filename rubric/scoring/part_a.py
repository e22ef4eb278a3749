"""Part A items (the 2x2 contact experiment): sample counts, proxy direction, N1/N4 agreement, array lengths."""

from __future__ import annotations

from ..metrics import align
from ..relations import cases_agree, proxy_change
from ..rubrics import Item
from .scorer import Context, NotMeasured, Outcome, credit, relation_verdict, scoring_rule

CONTACT_ROLES = ("N1", "N2", "N3", "N4")


@scoring_rule("sample_counts", reads=CONTACT_ROLES)
def sample_counts(ctx: Context, item: Item, a) -> Outcome:
    """The question names the finer and the coarser dt's sample counts (150 and 75 in the lesson, the variant's own
    otherwise); the answer's `samples_150` lists the cases with the first count, `samples_75` those with the second."""
    many, few = ctx.cases["N1"].sample_count, ctx.cases["N3"].sample_count
    counts = {role: len(ctx.result(role).arrays["t"]) for role in CONTACT_ROLES}
    want_many = sorted(role for role, n in counts.items() if n == many)
    want_few = sorted(role for role, n in counts.items() if n == few)
    ok = sorted(a.samples_150) == want_many and sorted(a.samples_75) == want_few
    return Outcome(credit(ok), f"{many} samples: {want_many}, {few} samples: {want_few}",
                   "measured array lengths: " + ", ".join(f"{role} {n}" for role, n in counts.items()),
                   {f"{role}_samples": n for role, n in counts.items()}, ctx.backends(*CONTACT_ROLES))


@scoring_rule("proxy_direction", reads=CONTACT_ROLES)
def proxy_direction(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("proxy_resolution")
    changes = [proxy_change(ctx.contact(coarse), ctx.contact(fine), tol) for coarse, fine in (("N1", "N2"), ("N3", "N4"))]
    invalid = [c.describe() for c in changes if not c.valid]
    if invalid:
        raise NotMeasured("; ".join(invalid))
    evidence = {}
    for c in changes:
        evidence |= {f"{c.coarse}_proxy_m": c.coarse_proxy, f"{c.fine}_proxy_m": c.fine_proxy}
    return Outcome(relation_verdict(a.direction, [c.direction for c in changes]), "the direction measured at fixed dt",
                   "; ".join(c.describe() for c in changes), evidence, ctx.backends(*CONTACT_ROLES))


@scoring_rule("n1_n4_agree", reads=("N1", "N4"))
def n1_n4_agree(ctx: Context, item: Item, a) -> Outcome:
    r1, r4 = ctx.result("N1"), ctx.result("N4")
    al = align("N1", r1.arrays, "N4", r4.arrays)
    if al.shared_samples == 0:
        raise NotMeasured("N1 and N4 share no sample times")
    agree = cases_agree(al, dz_tol=ctx.tol("n1_n4_max_dz"), dvz_tol=ctx.tol("n1_n4_max_dvz"))
    dz, dvz = al.max_abs_diff["z"], al.max_abs_diff["vz"]
    return Outcome(credit(a.agree == agree), f"agree={agree}",
                   f"max |dz| = {dz:.3g} m, max |dvz| = {dvz:.3g} m/s over {al.shared_samples} shared times "
                   f"{al.first_shared_times}...",
                   {"max_abs_dz_m": dz, "max_abs_dvz_m_s": dvz, "shared_samples": al.shared_samples},
                   ctx.backends("N1", "N4"))


@scoring_rule("array_lengths", reads=("N1", "N4"))
def array_lengths(ctx: Context, item: Item, a) -> Outcome:
    r1, r4 = ctx.result("N1"), ctx.result("N4")
    n1, n4 = len(r1.arrays["t"]), len(r4.arrays["t"])
    s1, s4 = r1.provenance.discretization.substep_dt, r4.provenance.discretization.substep_dt
    same = n1 == n4
    return Outcome(credit(a.same_length == same), f"same_length={same}",
                   f"engine substep_dt N1 {s1:g} s, N4 {s4:g} s; measured array lengths N1 {n1}, N4 {n4}",
                   {"N1_samples": n1, "N4_samples": n4, "N1_substep_dt_s": s1, "N4_substep_dt_s": s4},
                   ctx.backends("N1", "N4"))


@scoring_rule("one_number", reads=("N1", "N2"))
def one_number(ctx: Context, item: Item, a) -> Outcome:
    m1, m2 = ctx.maybe(ctx.contact, "N1"), ctx.maybe(ctx.contact, "N2")
    measured, evidence, backends = "no measured example available", {}, {}
    if m1 and m2:
        evidence = {"N1_proxy_m": m1.penetration_proxy, "N2_proxy_m": m2.penetration_proxy,
                    "N1_separation_samples": m1.separation_samples, "N2_separation_samples": m2.separation_samples}
        backends = ctx.backends("N1", "N2")
        measured = (f"N1 proxy {m1.penetration_proxy:.6f} m with {m1.separation_samples} separation samples; "
                    f"N2 proxy {m2.penetration_proxy:.6f} m with {m2.separation_samples} separation samples")
    return Outcome(credit(a.one_number_decides is False), "no: read proxy, contact, clearance and trajectory together",
                   measured, evidence, backends)
