"""Euro NCAP-style scoring of the `ncap_*` scenarios: outcome, colour and score per test speed.

Euro NCAP's AEB pedestrian tests (CPNA, CPFA, CPNC) test the car at 10-60 km/h in 10 km/h steps and
score, per test speed, whether the car avoided the dummy and, if not, how fast it hit it, as a colour. The
`ncap_*` scenarios draw one of those test speeds per seed; each test speed's row counts the episodes'
outcomes (`EpisodeResult.ncap_outcome`: avoided, outrun, impact, not tested), the avoidance rate over the
tested episodes, the mean impact speed of the impacts (the ego's speed when the contact began, as Euro
NCAP measures it; the key pedestrian is a dummy that reacts to nothing, `ConflictConfig.dummy`), the Euro
NCAP 2026 colours with their points, and the NeuroNCAP score. Written into ``report.md`` and ``ncap.csv``.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from crossing_env.safety import DEFAULT_METRICS
from crossing_eval.tasks import EpisodeRecord

PREFIX = "ncap_"
"""Scenarios scored this way: the built-in NCAP family and any scenario file named like it."""
BIN_KMH = 10.0
"""Spacing of Euro NCAP's test speeds (km/h): an episode's test speed is its car speed to the nearest."""


def _test_speed(speed_ms: float) -> int | None:
    """An episode's test speed (km/h): its car speed after reset to the nearest 10 km/h.

    The NCAP scenarios draw it from Euro NCAP's grid, so it is exact there.
    """
    if not math.isfinite(speed_ms):
        return None
    return int(round(speed_ms * 3.6 / BIN_KMH) * BIN_KMH)


COLOURS = ("green", "yellow", "orange", "brown", "red")
"""Euro NCAP's colours, best first."""
POINTS = {"green": 1.0, "yellow": 0.75, "orange": 0.5, "brown": 0.25, "red": 0.0}
"""Points per colour (Euro NCAP 2026)."""


def colour(test_kmh: float, outcome: str, impact_kmh: float) -> str | None:
    """Euro NCAP 2026's colour of one test: the impact speed's band at that test speed (None: not tested).

    At 10-20 km/h only avoidance counts (green, else red); at 30 km/h green 0 / brown <= 10 / red; at 40
    km/h green 0 / orange <= 10 / brown <= 20 / red; from 50 km/h green 0 / yellow <= 10 / orange <= 20 /
    brown <= 30 / red (impact speeds in km/h). The measured colour is the plain band, without the 2 km/h
    tolerance, which Euro NCAP applies only to check a carmaker's predicted colour (rating 2026 scorer,
    sec 4.2.4). Outrunning the dummy is not avoiding it: red.
    """
    if outcome == "not tested":
        return None
    if outcome == "avoided":
        return "green"
    if outcome == "outrun" or not math.isfinite(impact_kmh):
        return "red"
    if impact_kmh <= 0.0:
        return "green"
    if test_kmh <= 25:
        bands: tuple[tuple[str, float], ...] = ()
    elif test_kmh <= 35:
        bands = (("brown", 10.0),)
    elif test_kmh <= 45:
        bands = (("orange", 10.0), ("brown", 20.0))
    else:
        bands = (("yellow", 10.0), ("orange", 20.0), ("brown", 30.0))
    return next((name for name, limit in bands if impact_kmh <= limit), "red")


def neuro_ncap(test_kmh: float, outcome: str, impact_kmh: float) -> float:
    """NeuroNCAP's score of one test: 5 without a collision, else 4 * max(0, 1 - v_impact / v_no_action).

    v_no_action is the test speed; outrunning scores as an impact at the full speed (0); nan if untested.
    """
    if outcome == "not tested":
        return math.nan
    if outcome == "avoided":
        return 5.0
    if outcome == "outrun" or not math.isfinite(impact_kmh):
        return 0.0
    return 4.0 * max(0.0, 1.0 - impact_kmh / test_kmh)


OUTCOMES = ("avoided", "outrun", "impact", "not tested")
"""An NCAP episode's outcome (`EpisodeResult.ncap_outcome`), in the table's order."""


@dataclass(frozen=True)
class NcapRow:
    """One (scenario, policy, test speed) of the NCAP table."""

    scenario: str
    policy: str
    test_kmh: int
    """The test speed (km/h)."""
    counts: dict[str, int]
    """Episodes per outcome (`OUTCOMES`)."""
    colours: dict[str, int]
    """Tested episodes per Euro NCAP colour (`COLOURS`)."""
    impact_kmh: float
    """Mean impact speed (the car's speed at contact) of the impact episodes, km/h; nan if none."""
    points: float
    """Mean Euro NCAP points of the tested episodes (green 1 ... red 0); nan if none was tested."""
    neuro_ncap: float
    """Mean NeuroNCAP score of the tested episodes (0-5); nan if none was tested."""

    @property
    def episodes(self) -> int:
        """Episodes at this test speed."""
        return sum(self.counts.values())

    @property
    def tested(self) -> int:
        """Episodes in which the dummy was released: the test ran."""
        return self.episodes - self.counts["not tested"]

    @property
    def avoidance(self) -> float:
        """Avoided / tested (outrunning is not avoiding; untested episodes count for nothing); nan if none."""
        return self.counts["avoided"] / self.tested if self.tested else math.nan


def _outcome(result: dict) -> str:
    """The episode's outcome; records written before outcomes existed: impact or avoided from the contacts."""
    outcome = result.get("ncap_outcome") or ""
    if outcome:
        return outcome
    return "impact" if result.get("pedestrian_collisions", 0) > 0 else "avoided"


def ncap_rows(records: Sequence[EpisodeRecord]) -> list[NcapRow]:
    """One row per (scenario, policy, test speed) of the `ncap_*` episodes, in that order."""
    groups: dict[tuple[str, str, int], list[EpisodeRecord]] = defaultdict(list)
    for rec in records:
        name = Path(rec.task.scenario).stem
        test = _test_speed(rec.initial_speed)
        if name.startswith(PREFIX) and test is not None:
            groups[(name, rec.task.policy, test)].append(rec)
    rows = []
    for (name, policy, test), recs in sorted(groups.items()):
        counts = dict.fromkeys(OUTCOMES, 0)
        colours = dict.fromkeys(COLOURS, 0)
        speeds, points, scores = [], [], []
        for r in recs:
            outcome = _outcome(r.result)
            counts[outcome] += 1
            impact = math.nan
            speed = r.result.get("ncap_impact_speed", r.result.get("max_impact_speed"))
            if outcome == "impact" and speed is not None:
                impact = 3.6 * float(speed)
                speeds.append(impact)
            band = colour(test, outcome, impact)
            if band is not None:
                colours[band] += 1
                points.append(POINTS[band])
                scores.append(neuro_ncap(test, outcome, impact))
        rows.append(
            NcapRow(
                name,
                policy,
                test,
                counts,
                colours,
                sum(speeds) / len(speeds) if speeds else math.nan,
                sum(points) / len(points) if points else math.nan,
                sum(scores) / len(scores) if scores else math.nan,
            )
        )
    return rows


NCAP_CSV_FIELDS = (
    "scenario",
    "policy",
    "test_speed_kmh",
    "episodes",
    *(f"{o.replace(' ', '_')}" for o in OUTCOMES),
    "avoidance_of_tested",
    *COLOURS,
    "ncap_points",
    "neuro_ncap",
    "impact_speed_kmh",
)
"""Columns of ``ncap.csv`` (one row per scenario, policy and test speed)."""


def ncap_csv_rows(rows: Sequence[NcapRow]) -> list[list[object]]:
    """The rows of ``ncap.csv`` (nan stays nan; the writer makes it an empty cell)."""
    return [
        [
            r.scenario,
            r.policy,
            r.test_kmh,
            r.episodes,
            *(r.counts[o] for o in OUTCOMES),
            r.avoidance,
            *(r.colours[c] for c in COLOURS),
            r.points,
            r.neuro_ncap,
            r.impact_kmh,
        ]
        for r in rows
    ]


def _fmt(x: float, digits: int = 2) -> str:
    return "-" if math.isnan(x) else f"{x:.{digits}f}"


def ncap_markdown(records: Sequence[EpisodeRecord]) -> str:
    """The report section (empty when the run has no `ncap_*` scenario)."""
    rows = ncap_rows(records)
    if not rows:
        return ""
    lines = [
        "## NCAP-style scoring (ncap_* scenarios)",
        "",
        "One row per test speed (Euro NCAP's grid, 10-60 km/h; the car's speed after reset). Each episode is"
        " avoided (no contact with the dummy), outrun (no contact, but the car's rear cleared the dummy's"
        f" path less than {DEFAULT_METRICS.outrun_margin:g} s before the dummy reached the car's side: it got"
        " away by speed), impact, or not tested (the dummy was never released: the car never came near)."
        " Avoided = avoided / tested (outrun is not avoided; '-' = none tested). Colours are Euro NCAP"
        " 2026's bands of the impact speed at each test speed (10-20 km/h: only avoidance is green; 30:"
        " brown <= 10 km/h; 40: orange <= 10, brown <= 20; 50-60: yellow <= 10, orange <= 20, brown <= 30;"
        " else red; outrun is red), counted as G/Y/O/B/R over the tested episodes; points = their mean"
        " (green 1, yellow 0.75, orange 0.5, brown 0.25, red 0); NeuroNCAP = mean of 5 without a collision,"
        " else 4 x max(0, 1 - impact speed / test speed). Impact speed = mean relative impact speed: the"
        " car's speed at contact less the dummy's along the car's heading (0 for a crossing dummy).",
        "",
        "| scenario | policy | test km/h | episodes | avoided | outrun | impact | not tested | avoided (of"
        " tested) | G/Y/O/B/R | points | NeuroNCAP | impact km/h |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        c = row.counts
        bands = "/".join(str(row.colours[k]) for k in COLOURS)
        lines.append(
            f"| {row.scenario} | {row.policy} | {row.test_kmh} | {row.episodes} | {c['avoided']}"
            f" | {c['outrun']} | {c['impact']} | {c['not tested']} | {_fmt(row.avoidance)} | {bands}"
            f" | {_fmt(row.points)} | {_fmt(row.neuro_ncap)} | {_fmt(row.impact_kmh, 1)} |"
        )
    return "\n".join(lines) + "\n"


def format_ncap_table(rows: Sequence[NcapRow]) -> str:
    """The printed NCAP table: one line per scenario, policy and test speed, Euro NCAP's colours counted."""
    header = ["scenario", "policy", "km/h", "n", "avoid/outrun/impact/untested", "G/Y/O/B/R", "points"]
    header += ["NeuroNCAP", "impact km/h"]
    table = [header]
    for row in rows:
        c = row.counts
        table.append(
            [
                row.scenario,
                row.policy,
                str(row.test_kmh),
                str(row.episodes),
                f"{c['avoided']}/{c['outrun']}/{c['impact']}/{c['not tested']}",
                "/".join(str(row.colours[k]) for k in COLOURS),
                _fmt(row.points),
                _fmt(row.neuro_ncap),
                _fmt(row.impact_kmh, 1),
            ]
        )
    widths = [max(len(r[i]) for r in table) for i in range(len(header))]
    lines = [
        "  ".join(
            cell.ljust(w) if j < 2 else cell.rjust(w)
            for j, (cell, w) in enumerate(zip(r, widths, strict=True))
        )
        for r in table
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    lines.append(
        "NCAP: Euro NCAP 2026 colours per test speed (G/Y/O/B/R over the tested episodes; points green 1 ..."
        " red 0); outrun is red; impact speed relative to the dummy; definitions in report.md."
    )
    return "\n".join(lines)
