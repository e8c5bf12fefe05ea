"""The findings record (study.reporting.findings) in words: a sentence per claim with the run's
numbers, and the claims table, for the Markdown summary, the paper and the HTML report."""
from __future__ import annotations

import math

from study.reporting.tables import UNCERTAINTY_NOTE, Table

# The digits of each claim's unit: dB to 0.01, MSE to 0.1, a ratio to 0.01.
_DIGITS = {"dB": 2, "MSE": 1, "ratio": 2}


def _d(claim: dict) -> int:
    return next((d for k, d in _DIGITS.items() if claim["unit"].startswith(k)), 2)


def _num(x, d: int, sign: bool = True) -> str:
    if x is None or not math.isfinite(x):
        return "–"
    return f"{x:+.{d}f}" if sign else f"{x:.{d}f}"


def ours(claim: dict) -> str:
    e, d = claim["effect"], _d(claim)
    if not e:
        return "–"
    sign = claim["id"] != "cost_ratio"
    if e["n"] == 1:
        return _num(e["mean"], d, sign)
    return f"{_num(e['mean'], d, sign)} (mean; {_num(e['min'], d, sign)} to {_num(e['max'], d, sign)})"


def factor_text(claim: dict) -> str:
    f, d = claim.get("factor"), _d(claim)
    if not f:
        return ""
    share = f.get("share_explained")
    out = (f"With {f['control']} the difference is {_num(f['mean_without'], d)} on average, against "
           f"{_num(f['mean_with'], d)} with {f['name']}")
    if share is not None and math.isfinite(share):
        out += f": {f['name']} accounts for {100 * share:.0f} % of it"
    return out + "."


def sentence(claim: dict) -> str:
    """One claim, adjudicated, with this run's numbers."""
    where = sorted({(c["resolution"], c["protocol"]) for c in claim["cases"]})
    protos = ", ".join(sorted({p for _, p in where}))
    res = ", ".join(sorted({r for r, _ in where}))
    s = f"{claim['claim']} Thesis: {claim['thesis']}. "
    if not claim["cases"]:
        return s + "Not testable here: this study ran none of its cases."
    s += (f"Here ({res}; {protos}): {claim['verdict']}, {claim['holds']} of {claim['of']} cases on the thesis's "
          f"side beyond the uncertainty; {claim['unit']} {ours(claim)}.")
    if claim.get("factor"):
        s += " " + factor_text(claim)
    gt = claim.get("ground_truth")
    if gt:
        s += (f" Judged against {gt['name']}, {gt['holds']} of {gt['of']} cases take the thesis's side "
              f"({claim['unit'].split(',')[0]} {_num(gt['mean'], _d(claim))} on average, against "
              f"{_num(gt['mean_path_traced'], _d(claim))} against the path-traced reference).")
    if claim.get("resolution_note"):
        s += f" ({claim['resolution_note'][0].upper()}{claim['resolution_note'][1:]}.)"
    if claim.get("machine"):
        s += f" ({claim['machine']}.)"
    return s


def factor_sentence(f: dict) -> str:
    """A measured factor (study.reporting.findings' record 'factors') in words."""
    if f["id"] == "sharpen_strength":
        from study.reporting.sharpen_sweep import factor_sentence as sweep
        return sweep(f)
    if f["id"] == "hard_cases":
        from study.reporting.findings_hard import sentences
        return " ".join(sentences(f))
    if f["id"] == "rebuilt_scenes":
        g = f["scene_gap"]
        ex = "; ".join(f"{c} {_num(e['mean'], 2)} dB ({_num(e['min'], 2)} to {_num(e['max'], 2)})"
                       for c, e in f["excess"].items() if e)
        return (f"Our rebuilt scenes ({', '.join(f['resolutions'])}; {f['protocol']}): No AA and FXAA, which depend "
                f"on no TAA detail, are {_num(g['mean'], 2)} dB from the thesis's figures on average "
                f"({_num(g['min'], 2)} to {_num(g['max'], 2)} over {g['n']} scenes; No AA and FXAA differ from each "
                f"other by {f['spread']:.2f} dB on average), which is what the scenes, resolution and ground truth "
                f"alone move a figure. Beyond that gap: {ex}.")
    return ""


def summary(record: dict) -> list[str]:
    """The findings as sentences: a claim's each, a factor's (the hard cases: one a column)."""
    from study.reporting.findings_hard import sentences
    out = [sentence(c) for c in record["claims"]]
    for f in record.get("factors", []):
        out += sentences(f) if f["id"] == "hard_cases" else [t for t in [factor_sentence(f)] if t]
    return out


def table(record: dict) -> Table:
    def gt(c):
        g = c.get("ground_truth")
        return "–" if not g else f"{g['holds']} / {g['of']} ({_num(g['mean'], _d(c))})"
    rows = [[c["claim"], c["thesis"], ours(c), c["verdict"], f"{c['holds']} / {c['of']}", gt(c),
             factor_text(c) or "–"] for c in record["claims"]]
    res = ", ".join(record["resolutions"])
    return Table(f"The thesis's claims, adjudicated ({res}; static protocols: {', '.join(record['protocols'])})",
                 ["claim", "thesis", "ours", "verdict", "cases reproduced", "against the thesis's ground truth",
                  "what explains it"], rows,
                 "A case (one scene under one protocol) is reproduced when its whole interval lies on the thesis's "
                 "side: static differences ± the two figures' reference uncertainties in quadrature; ghosting means "
                 "± the 95 % bootstrap interval over frames widened by the reference's share. Every number is this "
                 "run's (tables/findings.json holds each case). Against the thesis's ground truth: the cases on "
                 "the thesis's side when every technique is judged against a 128-sample accumulation of our "
                 "raster, as the thesis judged, and the mean difference there.",
                 widths=[0.2, 0.12, 0.13, 0.08, 0.06, 0.1, 0.19])


def source_line(record: dict) -> str | None:
    """The study a findings record comes from, in words (its 'study' field), or None."""
    from study.reporting.source import study_line
    if not isinstance(record.get("study"), dict):
        return None
    return "From " + study_line(record["study"], record.get("resolutions") or []) + "."


def markdown(record: dict) -> str:
    src = source_line(record)
    lines = ["## Findings", ""] + ([f"*{src}*", ""] if src else []) + [f"- {s}" for s in summary(record)] + ["", table(record).markdown()]
    return "\n".join(lines)


def latex_summary(record: dict) -> str:
    """The sentences as a LaTeX itemize, for the paper's summary."""
    def esc(s: str) -> str:
        return (s.replace("\\", "\\textbackslash{}").replace("&", "\\&").replace("%", "\\%").replace("_", "\\_")
                .replace("#", "\\#").replace("–", "--").replace("−", "$-$").replace("×", "$\\times$"))
    items = "\n".join(f"\\item {esc(s)}" for s in summary(record))
    return "% generated by taa-study; do not edit\n\\begin{itemize}\n" + items + "\n\\end{itemize}\n"


def agreement_missed(agree: dict | None) -> list[str]:
    """The agreement targets a scene's check missed, as 'name (figure against target)'."""
    if not agree:
        return []
    from study.config.defaults import AGREEMENT_TARGETS as TARGETS
    met, out = agree.get("targets_met", {}), []
    if met.get("agreement_psnr_db") is False:
        out.append(f"agreement {_agreement_db(agree, 2)} dB < {TARGETS['agreement_psnr_db']:g} dB")
    if met.get("interior_max_abs_err") is False:
        out.append(f"interior error {agree['interior_max_abs_err']:.2g} > {TARGETS['interior_max_abs_err']:g}")
    if met.get("reference_noise_psnr_db") is False:
        out.append(f"reference noise {agree['reference_noise_psnr_db']:.1f} dB < "
                   f"{TARGETS['reference_noise_psnr_db']:g} dB")
    if met.get("reference_bound") is False:
        out.append(f"{agree['reference_over_bound']} reference pixels over the bound")
    if met.get("single_sample") is False:
        out.append("the raster took more than one sample per pixel")
    if met.get("objects_visible") is False:
        out.append("no object visible")
    return out


def _agreement_db(agree: dict, digits: int) -> str:
    """The agreement PSNR with the reference's share: '+- u' where that is small beside the MSE,
    else the floor it is checked at ('82.0, at least 60.3': its MSE's uncertainty near the MSE)."""
    psnr, u, floor = agree["agreement_psnr_db"], agree.get("agreement_u_db") or 0.0, agree.get("agreement_floor_db")
    if floor is not None and math.isinf(psnr) and math.isfinite(floor):
        return f"at least {floor:.{digits}f}"       # the MSE within the reference's noise
    if floor is not None and u > 1.0:
        return f"{psnr:.{digits}f}, at least {floor:.{digits}f}"
    return f"{psnr:.{digits}f}" + (f" ± {u:.2g}" if u >= 0.05 else "")


def agreement_line(agree: dict | None) -> str:
    """A scene's raster-against-reference check in one readable line."""
    if not agree:
        return ""
    from study.config.defaults import AGREEMENT_TARGETS as TARGETS
    missed = agreement_missed(agree)
    return (f"Raster against reference: {_agreement_db(agree, 2)} dB"
            + f" (target ≥ {TARGETS['agreement_psnr_db']:g} dB) over the mean of "
            f"{agree['raster_samples']} jittered raster frames; reference at {agree['reference_se_bound_lsb']:g} LSB "
            f"per pixel, {agree['reference_spp']} spp, noise {agree['reference_noise_psnr_db']:.1f} dB"
            + (" (removed with its halves; its share of the figure is the ±)" if agree.get("reference_rule") == "figures"
               else "") + ". "
            + ("Targets missed: " + "; ".join(missed) + "." if missed else "Every target met."))


def floor_note(agree: dict | None) -> str:
    """A table's note on its scene's raster/reference agreement."""
    if not agree:
        return ""
    missed = agreement_missed(agree)
    removed = " (removed with its halves)" if agree.get("reference_rule") == "figures" else ""
    return (f"Reference agreement (raster mean of {agree['raster_samples']} jittered frames vs reference): "
            f"{_agreement_db(agree, 1)} dB; reference noise "
            f"{agree['reference_noise_psnr_db']:.1f} dB at {agree['reference_spp']} spp{removed}"
            + (f" – below its target ({'; '.join(missed)}): every figure of this scene carries that error." if missed
               else ""))


def precision_note(res) -> str:
    """A table's note on the bounds its references were refined to."""
    bounds = sorted(set(res.reference_bounds_lsb.values()) or {res.reference_bound_lsb}, reverse=True)
    if len(bounds) > 1:
        n = {b: sum(1 for v in res.reference_bounds_lsb.values() if v == b) for b in bounds}
        refined = (f"{bounds[0]:g} LSB per pixel, " + ", ".join(f"{n[b]} of its {len(res.reference_bounds_lsb)} "
                   f"instants to {b:g}" for b in bounds[1:]))
    else:
        refined = f"{bounds[0]:g} LSB per pixel"
    return f" References refined to {refined} (study.engine.precision). " + UNCERTAINTY_NOTE
