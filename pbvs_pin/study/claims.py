"""The paper's claims as rules of named clauses, and a run's verdict clause by clause.

Each claim of the paper's §5 is decided by a rule (:data:`CLAIMS`): a list of clauses, each a
figure of the run's summary (:func:`pbvs_pin.sim.metrics.summarize`) against a threshold,
e.g. ``last 5 s``: ``max_abs_error_final_window_px < 8 px``. The rule's text, as the report
prints it, is its clauses' words joined. :func:`judge` gives a run's verdict: whether it
meets the rule, and every clause with its measured value, threshold and whether it holds, so
that a failed run says which clause failed and by how much (:func:`clause_text`).

**Runs too short to judge.** Every rule reads the last :data:`~pbvs_pin.sim.metrics.FINAL_WINDOW`
seconds of the run and the oscillation over a window of that length after the start-up
transient (:data:`~pbvs_pin.sim.metrics.TRANSIENT`). A run whose last logged instant is
before ``TRANSIENT + FINAL_WINDOW`` (7 s) is not judged (``met`` None, with the reason in
``not_judged``): its final window would hold the start-up transient, or be shorter than the
rule's window, and a verdict of "not met" would judge the transient, not the claim. Such runs
are flagged, not refused: a short run is a legitimate check of a set-up; its clauses' figures
are still given.
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pbvs_pin.exceptions import PbvsError
from pbvs_pin.sim.metrics import FINAL_WINDOW, OSCILLATION_CUTOFF_HZ, TRANSIENT

RELATIONS: dict[str, Callable[[float, float], bool]] = {
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
}
"""The relation a clause's figure must have to its threshold."""

NEGATIONS = {"<": ">=", "<=": ">", ">": "<="}
"""How a failed clause's relation is printed (``47.6 px >= 8 px``)."""

JUDGED_FROM_S = TRANSIENT + FINAL_WINDOW
"""Last logged instant [s] a run needs to be judged: its final window after the transient."""


@dataclass(frozen=True)
class Clause:
    """One condition of a rule: a figure of a run's summary against a threshold.

    Attributes:
        name: Short name, as verdicts print it (``"last 5 s"``).
        text: The clause in the rule's words (``"max abs(e) over the last 5 s < 8 px"``).
        figure: The summary's key of the measured value.
        relation: ``"<"``, ``"<="`` or ``">"``: what holds between value and threshold.
        threshold: The threshold in ``unit``, or how to read it from the summary (half the
            image height).
        unit: Unit of value and threshold (``"px"``, ``"rad"``, ``"m"``, ``"samples"``).
        optional: The clause holds when the figure is None (no obstacle, no joint limits
            recorded); otherwise a missing figure (no finite value) fails it.
    """

    name: str
    text: str
    figure: str
    relation: str
    threshold: float | Callable[[dict[str, Any]], float]
    unit: str
    optional: bool = False

    def __post_init__(self) -> None:
        """Refuse a relation other than those of :data:`RELATIONS`.

        Raises:
            PbvsError: Naming the clause and the relation.
        """
        if self.relation not in RELATIONS:
            raise PbvsError(
                f"clause {self.name!r}: relation {self.relation!r}; expected one of "
                f"{list(RELATIONS)}"
            )

    def judge(self, summary: dict[str, Any]) -> dict[str, Any]:
        """The clause on a run: ``name, figure, value, relation, threshold, unit, holds``."""
        value = summary[self.figure]
        threshold = self.threshold(summary) if callable(self.threshold) else self.threshold
        if value is None:
            holds = self.optional
        else:
            holds = bool(RELATIONS[self.relation](value, threshold))
        return {
            "name": self.name, "figure": self.figure, "value": value,
            "relation": self.relation, "threshold": float(threshold), "unit": self.unit,
            "holds": holds,
        }  # fmt: skip


@dataclass(frozen=True)
class Claim:
    """One of the paper's claims (§5) and the rule that decides whether a run meets it.

    Attributes:
        text: The paper's claim.
        clauses: The rule: 'met' means every clause holds.
    """

    text: str
    clauses: tuple[Clause, ...]

    @property
    def rule(self) -> str:
        """The rule, in words, as the report prints it."""
        return "; ".join(clause.text for clause in self.clauses)


SUSTAINED_OSCILLATION_PX = 3.0
"""Largest RMS of the error's part above the oscillation cut-off, over any 5 s window [px]."""

JOINT_LIMIT_TOLERANCE = 0.01
"""Largest excursion of an arm joint past its position limit [rad or m]."""

SOUND = (
    Clause("target lost", "target never lost", "target_lost_samples", "<=", 0, "samples"),
    Clause(
        "past joint limits", f"no joint more than {JOINT_LIMIT_TOLERANCE:g} past its limits",
        "joint_limit_violation", "<=", JOINT_LIMIT_TOLERANCE, "rad or m", optional=True,
    ),
    Clause(
        "oscillation",
        f"no sustained oscillation (the error's part above {OSCILLATION_CUTOFF_HZ:g} Hz < "
        f"{SUSTAINED_OSCILLATION_PX:g} px RMS over every 5 s window)",
        "oscillation_rms_px", "<", SUSTAINED_OSCILLATION_PX, "px",
    ),
)  # fmt: skip
"""What every claim requires besides its own figures: a run that holds only through an
artefact (a lost target, a joint past its stop, an oscillation inside a loose bound) is not
a pass."""

SOUND_RULE = "; ".join(clause.text for clause in SOUND)
""":data:`SOUND` in words."""


def _final(threshold: float, words: str = "max abs(e) over the last 5 s", note: str = "") -> Clause:
    """The clause on the largest absolute feature error over the final window [px]."""
    text = f"{words} < {threshold:g} px{note}"
    return Clause("last 5 s", text, "max_abs_error_final_window_px", "<", threshold, "px")


BOUNDED = (
    Clause(
        "after 2 s", "max abs(e) after 2 s < half the image height",
        "max_abs_error_after_transient_px", "<", lambda s: s["image_height_px"] / 2, "px",
    ),
    Clause("clearance", "min clearance > 0", "min_clearance_m", ">", 0.0, "m", optional=True),
)  # fmt: skip
"""The error stays bounded after the transient and the platform never touches an obstacle."""

CLAIMS = {
    "experiment1": Claim(
        "errors ultimately bounded, final max |error| < 8 px", (_final(8.0), *SOUND)
    ),
    "experiment2": Claim(
        "errors bounded while avoiding the obstacle; arm returns to max manipulability",
        (
            *BOUNDED,
            Clause(
                "arm to theta_d",
                "arm within 0.1 rad of theta_d over the last 5 s",
                "posture_error_final_window_rad",
                "<",
                0.1,
                "rad",
            ),
            _final(8.0, "last 5 s"),
            *SOUND,
        ),
    ),
    "experiment3": Claim(
        "errors bounded with a 20% kinematic model error (degraded but acceptable)",
        (*BOUNDED, _final(12.0, "last 5 s", " (1.5 times Exp. 1's 8 px)"), *SOUND),
    ),
    "experiment4": Claim("errors converge to zero (perfect knowledge)", (_final(0.5), *SOUND)),
}
"""The paper's claim for each experiment (§5) and its rule (the design notes, §4)."""


def judge(summary: dict[str, Any]) -> dict[str, Any]:
    """A run's verdict by its experiment's rule, clause by clause.

    Args:
        summary: The run's summary (:func:`pbvs_pin.sim.metrics.summarize`); its
            ``scenario`` names the experiment whose rule applies.

    Returns:
        ``met``: True or False, or None when the run is not judged; ``not_judged``: why not
        (no claim for the scenario, or a run too short: module docstring), else None;
        ``rule``: the rule's text (None without a claim); ``clauses``: each clause of
        :meth:`Clause.judge`, in the rule's order.
    """
    claim = CLAIMS.get(summary["scenario"])
    if claim is None:
        reason = f"scenario {summary['scenario']!r} is none of the paper's experiments"
        return {"met": None, "not_judged": reason, "rule": None, "clauses": []}
    clauses = [clause.judge(summary) for clause in claim.clauses]
    reason = too_short(summary["duration_s"])
    met = None if reason else all(c["holds"] for c in clauses)
    return {"met": met, "not_judged": reason, "rule": claim.rule, "clauses": clauses}


def too_short(end: float) -> str | None:
    """Why a run whose last logged instant is ``end`` [s] is not judged; None if it is."""
    if end < FINAL_WINDOW:
        return f"run logged to {end:g} s, shorter than the rule's {FINAL_WINDOW:g} s window"
    if end < JUDGED_FROM_S:
        return (
            f"run logged to {end:g} s: the rule's last {FINAL_WINDOW:g} s would start at "
            f"{end - FINAL_WINDOW:g} s, inside the {TRANSIENT:g} s start-up transient (a run "
            f"is judged from {JUDGED_FROM_S:g} s logged on: a duration above {JUDGED_FROM_S:g} s)"
        )
    return None


def claim_met(summary: dict[str, Any]) -> bool | None:
    """Whether a run meets its experiment's claim; None without a claim or when not judged."""
    return judge(summary)["met"]


def failed(judgement: dict[str, Any]) -> list[dict[str, Any]]:
    """The clauses of a verdict (:func:`judge`) that do not hold."""
    return [clause for clause in judgement["clauses"] if not clause["holds"]]


def clause_text(clause: dict[str, Any]) -> str:
    """A judged clause with its figures: ``last 5 s: 47.6 px >= 8 px`` when it fails.

    A holding clause prints its own relation (``last 5 s: 1.68 px < 8 px``); an optional
    clause without a figure, ``clearance: no figure``. The value gets the digits that tell
    it from the threshold. A NaN value (a robot that fell: no finite error) prints as no
    figure too, as it reads back from ``summary.json``, which stores it as null.
    """
    value, threshold, unit = clause["value"], clause["threshold"], clause["unit"]
    if value is None or value != value:  # None, or NaN
        return f"{clause['name']}: no figure"
    relation = clause["relation"] if clause["holds"] else NEGATIONS[clause["relation"]]
    limit = f"{threshold:g}"
    digits = 3
    while f"{value:.{digits}g}" == limit and digits < 12:
        digits += 1
    return f"{clause['name']}: {value:.{digits}g} {unit} {relation} {limit} {unit}"


def verdict_parts(judgement: dict[str, Any]) -> tuple[str, str]:
    """``("met", "")``, ``("NOT met", <failed clauses>)`` or ``("not judged", <why>)``."""
    if judgement["met"] is None:
        return "not judged", judgement["not_judged"]
    if judgement["met"]:
        return "met", ""
    return "NOT met", "; ".join(map(clause_text, failed(judgement)))


def verdict_text(judgement: dict[str, Any]) -> str:
    """``met``, ``NOT met: <failed clauses>`` or ``not judged: <why>``.

    Args:
        judgement: A verdict of :func:`judge`, or a summary that holds one (``summary.json``).
    """
    head, detail = verdict_parts(judgement)
    return f"{head}: {detail}" if detail else head


def verdict_lines(summary: dict) -> str | None:
    """The two lines ``pbvs-pin run`` prints: the verdict on the paper's claim, and the rule.

    The first names the failed clauses with their figures (every clause when all hold), or
    why the run is not judged (:func:`pbvs_pin.study.claims.judge`); the second gives the rule.
    """
    judgement = judge(summary)
    if judgement["rule"] is None:
        return None
    head, detail = verdict_parts(judgement)
    if head == "met":
        detail = "; ".join(map(clause_text, judgement["clauses"]))
    said = {"met": "meets", "NOT met": "does NOT meet", "not judged": "is not judged against"}
    return (
        f"verdict: {summary['scenario']} {said[head]} the paper's claim "
        f"({CLAIMS[summary['scenario']].text}): {detail}\nrule: {judgement['rule']}"
    )
