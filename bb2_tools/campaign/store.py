"""A campaign's directory: the run journal, the results tables and ``campaign.yaml``.

``runs.jsonl`` is the journal: one JSON line per finished run, appended by the driver with a single
``write`` on an ``O_APPEND`` descriptor as each run lands (and fsync'ed at least every second), so a SIGKILL
of the driver loses only the runs in flight.  On ``--resume`` a torn last line is cut off and the indices in
the journal are the runs done.  ``results.parquet`` / ``results.csv`` are built from the journal (sorted by
index, one row per index, streamed in chunks) and replaced atomically; so is ``campaign.yaml``.
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import time
from pathlib import Path
from typing import Any, Iterator

import yaml

from bb2_sim.yaml_files import load as load_yaml
from bb2_tools.campaign.errors import SpecError
from bb2_tools.campaign.figures import figure_kinds, json_safe
from bb2_tools.campaign.spec import CampaignSpec

__all__ = ["JOURNAL", "RESULTS_PARQUET", "RESULTS_CSV", "CAMPAIGN_YAML", "REPORT_HTML", "Journal",
           "results_schema", "write_results", "write_campaign_yaml", "check_campaign_yaml", "software_version",
           "atomic_write_text", "read_results"]

JOURNAL = "runs.jsonl"
RESULTS_PARQUET = "results.parquet"
RESULTS_CSV = "results.csv"
CAMPAIGN_YAML = "campaign.yaml"
REPORT_HTML = "report.html"
_FSYNC_EVERY_S = 1.0
_CHUNK = 5_000


def atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


class Journal:
    """The append-only journal of finished runs (see the module docstring)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._fd: int | None = None
        self._last_sync = 0.0

    def recover(self) -> set[int]:
        """Cut a torn last line off and return the indices recorded (each line a complete JSON row; streamed)."""
        if not self.path.exists():
            return set()
        with open(self.path, "r+b") as fh:
            size = fh.seek(0, os.SEEK_END)
            end = size
            while end > 0:                      # the last newline, read backwards in blocks
                start = max(0, end - 65536)
                fh.seek(start)
                block = fh.read(end - start)
                k = block.rfind(b"\n")
                if k >= 0:
                    end = start + k + 1
                    break
                end = start
            if end < size:
                fh.truncate(end)
                fh.flush()
                os.fsync(fh.fileno())
        return {int(row["index"]) for row in self.rows()}

    @staticmethod
    def _rows(lines: Any) -> Iterator[dict[str, Any]]:
        for line in lines:
            try:
                row = json.loads(line)
            except ValueError:
                continue
            if isinstance(row, dict) and isinstance(row.get("index"), int):
                yield row

    def rows(self) -> Iterator[dict[str, Any]]:
        """Every complete row, in the order they landed (streamed)."""
        if not self.path.exists():
            return
        with open(self.path, "rb") as fh:
            yield from self._rows(fh)

    def append(self, row: dict[str, Any]) -> None:
        if self._fd is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        data = (json.dumps({k: json_safe(v) for k, v in row.items()}, allow_nan=False) + "\n").encode()
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        now = time.monotonic()
        if now - self._last_sync >= _FSYNC_EVERY_S:
            os.fsync(self._fd)
            self._last_sync = now

    def close(self) -> None:
        if self._fd is not None:
            os.fsync(self._fd)
            os.close(self._fd)
            self._fd = None


# ------------------------------------------------------------------------------------------ tables
def results_schema(spec: CampaignSpec) -> Any:
    import pyarrow as pa

    arrow = {"bool": pa.bool_(), "int": pa.int64(), "float": pa.float64(), "str": pa.string(), "json": pa.string()}
    cols = [("index", pa.int64()), ("seed", pa.int64())]
    cols += [(v.key, arrow[v.column_kind]) for v in spec.vary]
    cols += [(n, arrow[k]) for n, k in figure_kinds(spec.target, spec.maneuver, spec.collect).items()]
    cols += [("status", pa.string()), ("message", pa.string()), ("wall_time_s", pa.float64())]
    return pa.schema(cols)


def write_results(out: Path, spec: CampaignSpec, journal: Journal) -> Any:
    """Build results.parquet and results.csv from the journal (sorted by index, deduplicated); returns the
    table."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    schema = results_schema(spec)
    tables, chunk = [], []
    for row in journal.rows():
        chunk.append(row)
        if len(chunk) >= _CHUNK:
            tables.append(pa.Table.from_pylist(chunk, schema=schema))
            chunk = []
    tables.append(pa.Table.from_pylist(chunk, schema=schema))
    table = pa.concat_tables(tables).sort_by("index")
    idx = table.column("index").to_numpy()
    if len(idx) > 1 and (idx[1:] == idx[:-1]).any():
        keep = np.ones(len(idx), bool)
        keep[1:] = idx[1:] != idx[:-1]
        table = table.filter(pa.array(keep))
    for name, writer in ((RESULTS_PARQUET, lambda f: pq.write_table(table, f)),
                         (RESULTS_CSV, lambda f: pacsv.write_csv(table, f))):
        tmp = out / f".{name}.tmp{os.getpid()}"
        writer(str(tmp))
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, out / name)
    return table


def read_results(out: str | Path) -> Any:
    import pyarrow.parquet as pq

    return pq.read_table(Path(out) / RESULTS_PARQUET)


# ------------------------------------------------------------------------------------------ campaign.yaml
def software_version() -> dict[str, Any]:
    from importlib import metadata

    import numpy

    try:
        version = metadata.version("bb2-sim-suite")
    except metadata.PackageNotFoundError:
        version = "unknown"
    info: dict[str, Any] = {"package": "bb2-sim-suite", "version": version, "python": platform.python_version(),
                            "numpy": numpy.__version__}
    repo = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True, timeout=10)
        if head.returncode == 0:
            info["git_commit"] = head.stdout.strip()
            dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=repo,
                                   capture_output=True, text=True, timeout=10)
            info["git_dirty"] = bool(dirty.stdout.strip())
    except (OSError, subprocess.SubprocessError):
        pass
    return info


def write_campaign_yaml(out: Path, spec: CampaignSpec, extra: dict[str, Any] | None = None) -> None:
    doc = {"campaign": spec.to_doc(), "software": software_version(),
           "written": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    if extra:
        doc.update(extra)
    atomic_write_text(out / CAMPAIGN_YAML, yaml.safe_dump(doc, sort_keys=False, allow_unicode=True))


def check_campaign_yaml(out: Path, spec: CampaignSpec) -> None:
    """On --resume: the directory must hold the same campaign (same resolved SPEC)."""
    f = out / CAMPAIGN_YAML
    if not f.exists():
        raise SpecError(f"--resume: {out} holds no {CAMPAIGN_YAML}")
    old = (load_yaml(f.read_text()) or {}).get("campaign")
    new = load_yaml(yaml.safe_dump(spec.to_doc()))
    if old != new:
        diff = sorted(k for k in set(old or {}) | set(new) if (old or {}).get(k) != new.get(k))
        raise SpecError(f"--resume: {out} holds a different campaign (differs in: {', '.join(diff)})")
