"""A sweep's rows on disk: written as cases finish, resumed after an interruption, finished in case order.

While the sweep runs, each finished row is one line appended (and flushed) to ``OUTPUT.partial``, a CSV with
the header of :data:`~nurbsinterp.sweep.case.COLUMNS`: a sweep that is interrupted or killed keeps every row
written but the one being written, which a rerun drops.  A rerun with the same output reads the partial file
(or, after a finished sweep, OUTPUT itself) and skips every case whose fingerprint has an ``ok`` or ``failed``
row there; ``error``, ``lost`` and ``timeout`` rows are computed again.  At the end the rows are copied in case order into
OUTPUT (a temporary file renamed into place: OUTPUT is only ever whole) and the partial file is removed.

Memory: the client keeps, per case, its fingerprint and the byte offset of its row (about 100 bytes a case),
never the rows themselves; the summary keeps bounded lists (:class:`Summary`).
"""
from __future__ import annotations

import csv
import heapq
import io
import math
import os

from ..errors import UsageError
from .case import COLUMNS

DONE = ("ok", "failed")  # statuses a rerun keeps; error, lost and timeout rows are computed again
HEADER = ",".join(COLUMNS) + "\n"
FAILED_SHOWN = 20
WORST_MEASURES = (("contour_error_max_mm", "contour error max (mm)"), ("worst_limit_ratio", "limit ratio"),
                  ("deviation_max_mm", "deviation from the program (mm)"), ("motion_time_s", "motion time (s)"))


def cell(value) -> str:
    """A value as the CSV writes it: empty for None, repr for floats (shortest round trip)."""
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return str(value)


def row_line(row: dict) -> str:
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerow([cell(row.get(c)) for c in COLUMNS])
    return out.getvalue()


#: columns of text, never read back as numbers (a fingerprint of decimal digits is still a fingerprint)
TEXT_COLUMNS = frozenset(("case_fingerprint", "program", "program_sha256", "program_options", "machine", "servo", "profile", "accdec", "interpolator",
                          "precompensate", "planner", "status", "error", "limits_held", "worst_limit", "worker"))


def parse(column: str, value: str):
    """A CSV cell of *column* back: None, its text, an int or a float."""
    if value == "":
        return None
    if column in TEXT_COLUMNS:
        return value
    for kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            pass
    return value


class Partial:
    """OUTPUT.partial: rows appended as cases finish; what an earlier run left, indexed by fingerprint."""

    def __init__(self, output: str, fresh: bool = False):
        self.output = output
        self.path = output + ".partial"
        self.offsets = {}  # fingerprint -> byte offset of its row in the partial file
        if fresh and os.path.exists(self.path):
            os.unlink(self.path)
        if not os.path.exists(self.path) and not fresh and os.path.isfile(output):
            self._copy_finished(output)
        if os.path.exists(self.path):
            self._read()
        else:
            with open(self.path, "w", encoding="utf-8") as fh:
                fh.write(HEADER)
        self.fh = open(self.path, "a", encoding="utf-8", newline="")

    def _copy_finished(self, output):
        """A finished sweep's OUTPUT as the partial file a rerun appends to."""
        with open(output, encoding="utf-8", newline="") as src:
            if src.readline() != HEADER:
                raise UsageError(f"{output}: not the results of this version's sweep (another header): give another "
                                 "-o, or --fresh to compute every case again")
            with open(self.path, "w", encoding="utf-8", newline="") as dst:
                dst.write(HEADER)
                for line in src:
                    dst.write(line)

    def _read(self):
        """Index the rows a run left; cut a torn last line (the run was killed while writing it)."""
        keep = 0
        with open(self.path, "rb") as fh:
            head = fh.readline()
            if head.decode("utf-8", "replace") != HEADER:
                raise UsageError(f"{self.path}: not the partial results of this version's sweep (another header): "
                                 "remove it, or give --fresh")
            at = fh.tell()
            keep = at
            for raw in fh:
                if not raw.endswith(b"\n"):
                    break  # torn: dropped
                fields = next(csv.reader([raw.decode("utf-8")]))
                if len(fields) == len(COLUMNS):
                    row = dict(zip(COLUMNS, fields))
                    if row["status"] in DONE:
                        self.offsets[row["case_fingerprint"]] = at
                at += len(raw)
                keep = at
        with open(self.path, "r+b") as fh:
            fh.truncate(keep)

    def done(self, fingerprint: str) -> bool:
        return fingerprint in self.offsets

    def add(self, row: dict) -> None:
        line = row_line(row)
        self.fh.seek(0, os.SEEK_END)
        at = self.fh.tell()
        self.fh.write(line)
        self.fh.flush()
        if row["status"] in DONE or row["case_fingerprint"] not in self.offsets:
            self.offsets[row["case_fingerprint"]] = at

    def close(self):
        if not self.fh.closed:
            self.fh.close()

    def finish(self, order):
        """OUTPUT: for each (fingerprint, labels) of *order* (case order) its row, with the case's index and the
        current sweep's labels ({column: value}: a row an earlier run wrote may have named them otherwise), written
        whole; the partial file removed."""
        from ..streams import open_output

        self.close()
        with open(self.path, "rb") as src, open_output(self.output) as out:
            out.write(HEADER.encode())
            for index, (fp, labels) in enumerate(order):
                src.seek(self.offsets[fp])
                fields = next(csv.reader([src.readline().decode("utf-8")]))
                row = {c: parse(c, v) for c, v in zip(COLUMNS, fields)}
                row.update(labels, case=index)
                out.write(row_line(row).encode())
        os.unlink(self.path)


def read_rows(path):
    """The rows of a finished sweep's file, one at a time, values parsed."""
    with open(path, encoding="utf-8", newline="") as fh:
        reader = csv.reader(fh)
        next(reader)
        for fields in reader:
            yield {c: parse(c, v) for c, v in zip(COLUMNS, fields)}


class Summary:
    """What the sweep's summary says, gathered row by row in bounded memory: counts, the first failed rows, and
    per machine and measure the worst case."""

    def __init__(self):
        self.counts = {"ok": 0, "failed": 0, "error": 0, "lost": 0, "timeout": 0}
        self.limits_broken = 0
        self.failed = []  # the first FAILED_SHOWN failed/error/lost rows (case order is not arrival order: a heap)
        self.failed_more = 0
        self.worst = {}  # (machine, column) -> (value, case, program, settings, what: the limit a ratio is of)

    def add(self, row: dict, settings: str = "") -> None:
        status = row["status"]
        self.counts[status] = self.counts.get(status, 0) + 1
        if status != "ok":
            item = (row["case"], row["program"], row["machine"], settings, row["error"] or "")
            if len(self.failed) < FAILED_SHOWN:
                heapq.heappush(self.failed, tuple(-x if i == 0 else x for i, x in enumerate(item)))
            else:
                self.failed_more += 1
                heapq.heappushpop(self.failed, tuple(-x if i == 0 else x for i, x in enumerate(item)))
            return
        if row.get("limits_held") == "no":
            self.limits_broken += 1
        for column, _ in WORST_MEASURES:
            value = row.get(column)
            if value is None:
                continue
            key = (row["machine"], column)
            if key not in self.worst or value > self.worst[key][0]:
                what = row.get("worst_limit") if column == "worst_limit_ratio" else None
                self.worst[key] = (value, row["case"], row["program"], settings, what)

    def failed_rows(self) -> list:
        """The failed rows kept, in case order: (case, program, machine, settings, error)."""
        return sorted((-c, *rest) for c, *rest in self.failed)
