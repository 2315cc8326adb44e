"""The summary of a batch: one row per study and surface, as ``summary.csv`` (and
``summary.parquet`` when pyarrow is installed), and ``summary.html``, a page with a thumbnail
per study and the table.

Columns (:data:`COLUMNS`): ``study``, ``status`` ("done": ran now, "skipped": done by an earlier
run with the same recipe and input, "failed", "pending": not run, the batch was interrupted),
``surface`` (name), ``value`` (label value or
isovalue), ``faces``, ``volume_mm3``, ``area_mm2``, ``closed`` (watertight), ``volume_change_pct``
and ``max_deviation_mm`` (smoothing: volume change and Hausdorff distance to the raw surface),
``decimation_volume_change_pct`` and ``decimation_max_error_mm``, ``warnings`` (how many the
study's report lists), ``seconds`` (the study's wall time), ``error`` (a failed study's one-line
reason; its row has no surface), ``input``. Values missing for a row (no smoothing, no
decimation) are empty.
"""
from __future__ import annotations

import csv
import html
import io
import os
import uuid
from pathlib import Path
from typing import Dict, List, Optional

from .state import THUMBNAIL

COLUMNS = (("study", "str"), ("status", "str"), ("surface", "str"), ("value", "float"),
           ("faces", "int"), ("volume_mm3", "float"), ("area_mm2", "float"), ("closed", "bool"),
           ("volume_change_pct", "float"), ("max_deviation_mm", "float"),
           ("decimation_volume_change_pct", "float"), ("decimation_max_error_mm", "float"),
           ("warnings", "int"), ("seconds", "float"), ("error", "str"), ("input", "str"))
_SURFACE_KEYS = ("faces", "volume_mm3", "area_mm2", "closed", "volume_change_pct", "max_deviation_mm",
                 "decimation_volume_change_pct", "decimation_max_error_mm")


def study_rows(study_id: str, status: str, path: str, report: Optional[Dict], error: str = "",
               seconds: Optional[float] = None) -> List[Dict]:
    """The summary rows of one study: one per surface of its report, or one with the error."""
    base = {name: None for name, _ in COLUMNS}
    base.update(study=study_id, status=status, input=str(path), error=error or "")
    if report is None:
        return [dict(base, seconds=seconds)]
    base.update(warnings=len(report.get("warnings", [])),
                seconds=(report.get("batch") or {}).get("seconds", seconds))
    rows = []
    for s in report.get("surfaces", []):
        row = dict(base, surface=s.get("name"), value=s.get("value"))
        row.update({k: s.get(k) for k in _SURFACE_KEYS})
        rows.append(row)
    return rows or [base]


def write_summary(out: Path, rows: List[Dict], title: str = "Anatomesh batch") -> Dict[str, Path]:
    """Write ``summary.csv``, ``summary.parquet`` (with pyarrow) and ``summary.html`` into
    ``out``; returns the paths written by format."""
    out = Path(out)
    written = {"csv": out / "summary.csv", "html": out / "summary.html"}
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=[name for name, _ in COLUMNS], lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: ("" if v is None else v) for k, v in r.items()} for r in rows)
    _write_text(written["csv"], buf.getvalue())
    if _write_parquet(out / "summary.parquet", rows):
        written["parquet"] = out / "summary.parquet"
    _write_text(written["html"], summary_html(out, rows, title))
    return written


def _write_parquet(path: Path, rows: List[Dict]) -> bool:
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return False
    types = {"str": pa.string(), "float": pa.float64(), "int": pa.int64(), "bool": pa.bool_()}
    schema = pa.schema([(name, types[kind]) for name, kind in COLUMNS])
    columns = {name: [_typed(r.get(name), kind) for r in rows] for name, kind in COLUMNS}
    tmp = path.with_name(path.name + f".{uuid.uuid4().hex[:8]}.part")
    pq.write_table(pa.table(columns, schema=schema), tmp)
    os.replace(tmp, path)
    return True


def _typed(value, kind: str):
    if value is None or value == "":
        return None
    return {"str": str, "float": float, "int": int, "bool": bool}[kind](value)


def _write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + f".{uuid.uuid4().hex[:8]}.part")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


# -- the HTML page ----------------------------------------------------------------------------
_CSS = """body{font:14px/1.4 system-ui,sans-serif;margin:1.5em;color:#222}
h1{font-size:1.4em;margin:0 0 .2em}.counts{color:#555;margin-bottom:1em}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(200px,1fr));gap:12px}
.card{border:1px solid #ddd;border-radius:6px;padding:8px;background:#fafafa}
.card img{width:100%;aspect-ratio:1;object-fit:contain;background:#fff;border-radius:4px}
.card .none{width:100%;aspect-ratio:1;display:flex;align-items:center;justify-content:center;
background:#fff;color:#b00;border-radius:4px}.id{font-weight:600;word-break:break-all}
.status{font-size:.8em;padding:1px 6px;border-radius:8px;color:#fff;margin-left:4px}
.done{background:#2a7}.skipped{background:#58a}.failed{background:#c33}.err{color:#b00;font-size:.85em}
.facts{font-size:.85em;color:#444}table{border-collapse:collapse;font-size:.85em;margin-top:1em}
td,th{border:1px solid #ddd;padding:2px 6px;text-align:right}td:nth-child(-n+3),th{text-align:left}"""


def summary_html(out: Path, rows: List[Dict], title: str) -> str:
    """The overview page: counts, one card per study (thumbnail, status, surfaces, faces, time,
    error), and the whole table under a fold. Thumbnails are linked, not embedded."""
    studies: Dict[str, List[Dict]] = {}
    for r in rows:
        studies.setdefault(r["study"], []).append(r)
    counts = {s: sum(1 for rs in studies.values() if rs[0]["status"] == s) for s in ("done", "skipped", "failed")}
    cards = [_card(out, sid, rs) for sid, rs in studies.items()]
    head = "".join(f"<th>{html.escape(n)}</th>" for n, _ in COLUMNS)
    body = "".join("<tr>" + "".join(f"<td>{_cell(r.get(n))}</td>" for n, _ in COLUMNS) + "</tr>" for r in rows)
    return (f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>{html.escape(title)}</title>"
            f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"
            f"<div class=counts>{len(studies)} studies: {counts['done']} done, {counts['skipped']} "
            f"unchanged since an earlier run, {counts['failed']} failed &middot; "
            f"<a href=summary.csv>summary.csv</a></div><div class=grid>{''.join(cards)}</div>"
            f"<details><summary>all rows ({len(rows)})</summary><table><tr>{head}</tr>{body}</table>"
            "</details></body></html>\n")


def _card(out: Path, study_id: str, rows: List[Dict]) -> str:
    first = rows[0]
    sid = html.escape(study_id)
    status = first["status"]
    link = html.escape(f"{study_id}/report.json", quote=True)
    if status != "failed" and (out / study_id / THUMBNAIL).exists():
        picture = (f'<a href="{link}"><img loading=lazy alt="{sid}" '
                   f'src="{html.escape(f"{study_id}/{THUMBNAIL}", quote=True)}"></a>')
    else:
        picture = "<div class=none>no picture</div>"
    surfaces = [r for r in rows if r["surface"] is not None]
    if status == "failed":
        facts = f"<div class=err>{html.escape(first['error'])}</div>"
    else:
        closed = sum(1 for r in surfaces if r["closed"])
        faces = sum(int(r["faces"] or 0) for r in surfaces)
        facts = (f"<div class=facts>{len(surfaces)} surfaces ({closed} closed), {faces:,} faces, "
                 f"{_cell(first['seconds'])} s</div>")
    return (f"<div class=card>{picture}<div><span class=id>{sid}</span><span class='status {status}'>"
            f"{status}</span></div>{facts}</div>")


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.4g}" if abs(v) < 1e5 else f"{v:.0f}"
    return html.escape(str(v))
