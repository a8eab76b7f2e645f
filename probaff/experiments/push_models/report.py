"""Tables and summary of the push-model study: means over folds and the thesis's claims checked.

`summarise` averages every (features, method, M) over the folds; `chapter5_section` and
`chapter4_section` are each chapter's Markdown section of the summary, with the
number of experts chosen by cross-validated NLPD and the thesis's findings checked on these
results (RMSE changes relative and averaged over the effect dimensions, so metres and radians
weigh alike; NLPD summed over the effects and averaged over held-out pushes).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from probaff.data.noise import PoseNoise
from probaff.eval.tables import markdown_table
from probaff.experiments.config_cli import settings_view
from probaff.experiments.push_models.claims import claim_lines, split_halfwidth, study_folds
from probaff.experiments.push_models.config import (
    CH4_EFFECTS,
    CH5_EFFECTS,
    PushModelStudyConfig,
)

__all__ = ["chapter4_section", "chapter5_section", "header", "summarise", "trials_section"]


def summarise(results: list[dict[str, Any]], effects: tuple[str, ...]) -> list[dict[str, Any]]:
    """Mean over the splits (repeats and folds) per (features, method, M).

    ``nlpd.total.ci95`` is the corrected resampled t half-width over the splits
    (`probaff.experiments.push_models.claims.split_halfwidth`).
    """
    folds = study_folds(results)
    table: dict[tuple[str, str, int], list[dict[str, Any]]] = {}
    for r in results:
        table.setdefault((r["features"], r["method"], r["M"]), []).append(r)
    rows = []
    for (feat, method, m), rs in sorted(table.items()):
        row: dict[str, Any] = {"features": feat, "method": method, "M": m, "folds": len(rs)}
        for metric in ("rmse", "nlpd", "coverage90"):
            mean = np.mean([r[metric] for r in rs], axis=0)
            for e, name in enumerate(effects):
                row[f"{metric}.{name}"] = float(mean[e])
        totals = [float(np.sum(r["nlpd"])) for r in rs]
        row["nlpd.total"] = float(np.mean(totals))
        row["nlpd.total.ci95"] = split_halfwidth(totals, folds)
        row["seconds"] = float(np.mean([r["seconds"] for r in rs]))
        rows.append(row)
    return rows


def _best_by_nlpd(rows: list[dict[str, Any]]) -> dict[tuple[str, str], int]:
    best: dict[tuple[str, str], tuple[float, int]] = {}
    for r in rows:
        k = (r["features"], r["method"])
        if k not in best or r["nlpd.total"] < best[k][0]:
            best[k] = (r["nlpd.total"], r["M"])
    return {k: v[1] for k, v in best.items()}


def _lookup(rows: list[dict[str, Any]], feat: str, method: str, m: int, col: str) -> float | None:
    for r in rows:
        if (r["features"], r["method"], r["M"]) == (feat, method, m):
            return r[col]
    return None


def _relative(
    rows: list[dict[str, Any]],
    a: tuple[str, str, int],
    b: tuple[str, str, int],
    dims: tuple[str, ...],
) -> float | None:
    """Mean over `dims` of RMSE(a) / RMSE(b) - 1, in %; `a`, `b` are (features, method, M)."""
    pairs = [(_lookup(rows, *a, f"rmse.{d}"), _lookup(rows, *b, f"rmse.{d}")) for d in dims]
    if any(x is None or y is None for x, y in pairs):
        return None
    return 100 * float(np.mean([x / y - 1 for x, y in pairs]))  # type: ignore[operator]


def _findings(rows: list[dict[str, Any]], method: str = "em") -> list[str]:
    """The thesis's chapter 5 claims, checked on these results (rows of `method`).

    RMSE changes are relative and averaged over the effect dimensions, so metres and radians
    weigh alike; NLPD is summed over the six effects and averaged over held-out pushes.
    """
    lines = []
    feats = sorted({r["features"] for r in rows if r["method"] == method})
    ms = sorted({r["M"] for r in rows if r["method"] == method})
    for feat in feats:
        changes: dict[int, float] = {
            m: v
            for m in ms
            if m != 1
            if (v := _relative(rows, (feat, method, m), (feat, method, 1), CH5_EFFECTS)) is not None
        }
        nl: dict[int, float] = {
            m: v for m in ms if (v := _lookup(rows, feat, method, m, "nlpd.total")) is not None
        }
        if changes and nl:
            txt = ", ".join(f"M={m}: {v:+.1f}%" for m, v in changes.items())
            best_nl = min(nl, key=lambda m: nl[m])
            best_rmse = min([1, *changes], key=lambda m: changes.get(m, 0.0))
            nl_txt = ", ".join(f"M={m}: {v:.2f}" for m, v in nl.items())
            lines.append(
                f"- features {feat}: RMSE relative to M=1 (negative = better; thesis: "
                f"-5.9 to -6.5%): {txt}; lowest RMSE at M={best_rmse}. NLPD: "
                f"{nl_txt}; lowest at M={best_nl} (thesis: M=3 best)."
            )
    o2 = CH5_EFFECTS[3:]
    for m in ms:
        a = _relative(rows, ("ocx", method, m), ("o", method, m), CH5_EFFECTS)
        b = _relative(rows, ("ocx", method, m), ("oc", method, m), CH5_EFFECTS)
        c = _relative(rows, ("ocx", method, m), ("o", method, m), o2)
        d = _relative(rows, ("ocx", method, m), ("oc", method, m), o2)
        if None not in (a, b, c, d):
            nls = [_lookup(rows, f, method, m, "nlpd.total") for f in ("o", "oc", "ocx")]
            lines.append(
                f"- M={m}: adding f_x changes RMSE by {a:+.1f}% vs f_o and {b:+.1f}% vs "
                f"f_o&f_c (thesis: -8.71% and -3.67%); o2: {c:+.1f}% and {d:+.1f}% "
                f"(thesis: -11.8% and -4.37%). NLPD f_o / f_o&f_c / all: "
                + " / ".join(f"{v:.2f}" for v in nls if v is not None)
                + "."
            )
        split, full, comb = (
            _lookup(rows, f, method, m, "rmse.o1.dz") for f in ("gx-eoc", "ocx", "oc")
        )
        if None not in (split, full, comb):
            lines.append(
                f"- M={m}: o1 along the push (dz) RMSE: gate-on-context {split:.4f} m, "
                f"all features {full:.4f} m, f_o&f_c {comb:.4f} m (thesis: the "
                "gate-on-context split is best)."
            )
    return lines


def _ch4_findings(rows: list[dict[str, Any]]) -> list[str]:
    """Chapter 4's claims (m = 3 best, dz gains over m = 1, context features) on these rows."""
    lines = []
    for method in ("clustered", "em"):
        for feat in sorted({r["features"] for r in rows if r["method"] == method}):
            ms = sorted({r["M"] for r in rows if r["method"] == method and r["features"] == feat})
            dz = {m: _lookup(rows, feat, method, m, "rmse.dz") for m in ms}
            nl = {m: _lookup(rows, feat, method, m, "nlpd.total") for m in ms}
            if 1 not in dz or dz[1] is None:
                continue
            gains = ", ".join(
                f"m={m}: {100 * (dz[1] - v):+.2f} cm"
                for m, v in dz.items()
                if m != 1 and v is not None
            )
            best = min((m for m in nl if nl[m] is not None), key=lambda m: nl[m])  # type: ignore
            lines.append(
                f"- {method}, features {feat}: dz RMSE gain over m=1 (thesis: m=2 "
                f"+1.83 cm, m=3 +2.63 cm): {gains}; lowest NLPD at m={best} (thesis: "
                "m=3 best)."
            )
        for m in sorted({r["M"] for r in rows if r["method"] == method}):
            rel = {
                d: _relative(rows, ("ocx", method, m), ("o", method, m), (d,)) for d in CH4_EFFECTS
            }
            if None not in rel.values():
                txt = ", ".join(f"{d} {v:+.1f}%" for d, v in rel.items())
                lines.append(
                    f"- {method}, m={m}: context features change RMSE by {txt} "
                    "(thesis: dth -13.79%, dy -8.93%, dz -9.75%)."
                )
    return lines


def _noise_text(config: PushModelStudyConfig) -> str:
    if config.pose_noise:
        return (
            f"Poses are observed with {PoseNoise()} (seeded, recorded in each dataset's "
            "manifest) and the experts' noise floor is sqrt(2) times that noise, the "
            "noise of an effect; scores are against the observed effects."
        )
    return "Poses are exact; the experts' noise floor is 1 % of each effect's standard deviation."


_KEYS = ("features", "method", "M")


def _scores_table(rows: list[dict[str, Any]], effects: tuple[str, ...], *extra: str) -> str:
    """The Markdown table of each effect's RMSE and the total NLPD with its interval."""
    rmse = [f"rmse.{e}" for e in effects]
    return markdown_table(rows, [*_KEYS, *rmse, "nlpd.total", "nlpd.total.ci95", *extra])


def header(config: PushModelStudyConfig) -> list[str]:
    """The summary's opening lines: the settings (`settings_view`), noise and methods."""
    return [
        "# Push-model study",
        "",
        f"Settings: `{settings_view(config)}`",
        "",
        _noise_text(config),
        "",
        "Methods: `em` is the gated mixture fitted by EM (default initialisation and "
        "restarts), `em-hard` the same fit predicting with its most probable expert only, "
        "`vi` SVI started from the EM fit, `clustered` chapter 4's model. `seconds` of EM "
        "is the whole path M = 1..max on a fold.",
        "",
    ]


def chapter5_section(
    rows5: list[dict[str, Any]], claims: list[dict[str, Any]] | None = None
) -> list[str]:
    """Chapter 5's Markdown section from its summary rows (`summarise`).

    `claims` (`probaff.experiments.push_models.claims.chapter5_claims`) adds the claims
    judged with intervals over the splits.
    """
    md = [
        "## Chapter 5: two-object pushes, mean over folds",
        "",
        _scores_table(rows5, CH5_EFFECTS, "seconds"),
        "90% interval coverage:",
        "",
        markdown_table(rows5, [*_KEYS, *(f"coverage90.{e}" for e in CH5_EFFECTS)], digits=2),
        "Number of experts chosen by cross-validated NLPD:",
        "",
    ]
    md += [
        f"- {feat} / {method}: M = {m}"
        for (feat, method), m in sorted(_best_by_nlpd(rows5).items())
    ]
    md += [
        "",
        "Checks of the thesis's findings (EM, gated mixture):",
        "",
        *_findings(rows5),
        "",
        "The same with the most probable expert only:",
        "",
        *_findings(rows5, "em-hard"),
        "",
    ]
    if claims:
        md += [
            "The claims judged split by split (paired: the same held-out pushes), with 95 % "
            "intervals over every repeat and fold (Nadeau and Bengio's corrected resampled "
            "t): `holds` when the interval lies on the thesis's "
            "side of 0, `refuted` when on the other, `not shown` when it holds 0 "
            "(`ch5_claims.csv` has every comparison):",
            "",
            *claim_lines(claims),
            "",
        ]
    return md


def trials_section(
    config: PushModelStudyConfig, rows: list[dict[str, Any]], claims: list[dict[str, Any]]
) -> list[str]:
    """The Markdown section of chapter 5's independent trials (``ch5_trials``).

    Args:
        config: The study's settings (the trials' sizes).
        rows: The trials' means (`summarise` of the trial rows).
        claims: `chapter5_claims` of the trial rows: one split per trial, so plain t
            intervals over the trials.
    """
    return [
        f"## Chapter 5 on fresh data: {config.ch5_trials} independent trials",
        "",
        f"Each trial simulates {config.ch5_pushes} training pushes and {config.ch5_trial_test} "
        "held-out pushes of its own (`trial_data`), fits every feature set's EM path on the "
        "first and scores it on the second. No two trials share a push, so the intervals are "
        "plain t intervals over the trials (`repeats`: trials; `won`: the share of trials "
        "whose own difference has the thesis's sign). Mean over trials:",
        "",
        _scores_table(rows, CH5_EFFECTS, "seconds"),
        "The claims judged trial by trial (paired: the same held-out pushes; "
        "`ch5_trial_claims.csv` has every comparison):",
        "",
        *claim_lines(claims),
        "",
    ]


def chapter4_section(rows4: list[dict[str, Any]]) -> list[str]:
    """Chapter 4's Markdown section from its summary rows (`summarise`)."""
    return [
        "## Chapter 4: single-object pushes near the battery",
        "",
        _scores_table(rows4, CH4_EFFECTS),
        "",
        "Checks of the thesis's chapter 4 findings:",
        "",
        *_ch4_findings(rows4),
        "",
    ]
