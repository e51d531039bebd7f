"""A sweep's rows on disk: written as cases finish, resumed after an interruption, finished in case order.

While the sweep runs, each finished row is one line appended (and flushed) to ``OUTPUT.partial``, a CSV with
the header of :data:`~nurbsinterp.sweep.case.COLUMNS`: a sweep that is interrupted or killed keeps every row
written but the one being written, which a rerun drops.  A rerun with the same output reads the partial file
(or, after a finished sweep, OUTPUT itself) and skips every case whose fingerprint has an ``ok`` or ``failed``
row there; ``error``, ``lost`` and ``timeout`` rows are computed again.  At the end the rows are copied in case order into
OUTPUT (a temporary file renamed into place: OUTPUT is only ever whole) and the partial file is removed.

Memory: the client's does not grow with the sweep.  Which cases there are (in order, with their labels) and where
each fingerprint's row is in the partial file are kept in SQLite's private temporary database (a file SQLite
removes from the directory as it opens it, so that nothing is left behind even by a killed sweep; about 150 bytes
a case; its page cache, 16 MiB at most, bounds what of it is in memory), never in Python objects; the rows
themselves stay in the files, and the summary keeps bounded lists (:class:`Summary`).
"""
from __future__ import annotations

import csv
import heapq
import io
import json
import math
import os
import sqlite3

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
    """OUTPUT.partial: rows appended as cases finish; what an earlier run left, indexed by fingerprint; the cases of
    this run in order (module docstring: the index is on disk)."""

    def __init__(self, output: str, fresh: bool = False):
        self.output = output
        self.path = output + ".partial"
        self.cases = 0
        # "": SQLite's private temporary database, on disk (SQLITE_TMPDIR, else /var/tmp, /usr/tmp or /tmp) and
        # unlinked as it opens: no journal, no fsync, never committed (its pages spill to that file)
        self.index = sqlite3.connect("")
        self._sql("PRAGMA journal_mode=OFF; PRAGMA synchronous=OFF; PRAGMA cache_size=-16384;"
                  "CREATE TABLE rows (fp TEXT PRIMARY KEY, at INTEGER NOT NULL) WITHOUT ROWID;"
                  "CREATE TABLE cases (n INTEGER PRIMARY KEY, fp TEXT NOT NULL, labels TEXT NOT NULL);", script=True)
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
                        self._at(row["case_fingerprint"], at)
                at += len(raw)
                keep = at
        with open(self.path, "r+b") as fh:
            fh.truncate(keep)

    def _sql(self, statement: str, values=(), script: bool = False):
        """A statement on the index; its failure (a full temporary disk) one line, as a bad input is."""
        try:
            return self.index.executescript(statement) if script else self.index.execute(statement, values)
        except sqlite3.Error as exc:
            raise UsageError(f"the sweep's index of its cases (SQLite's temporary file): {exc}") from None

    def _at(self, fingerprint: str, at: int, replace: bool = True) -> None:
        self._sql(f"INSERT OR {'REPLACE' if replace else 'IGNORE'} INTO rows VALUES (?, ?)", (fingerprint, at))

    def case(self, fingerprint: str, labels: dict) -> None:
        """The next case of this run, in order: its fingerprint and its labels ({column: value})."""
        self._sql("INSERT INTO cases VALUES (?, ?, ?)", (self.cases, fingerprint, json.dumps(labels)))
        self.cases += 1

    def done(self, fingerprint: str) -> bool:
        return self._sql("SELECT 1 FROM rows WHERE fp = ?", (fingerprint,)).fetchone() is not None

    def add(self, row: dict) -> None:
        line = row_line(row)
        self.fh.seek(0, os.SEEK_END)
        at = self.fh.tell()
        self.fh.write(line)
        self.fh.flush()
        self._at(row["case_fingerprint"], at, replace=row["status"] in DONE)  # a kept row is not displaced

    def close(self):
        if not self.fh.closed:
            self.fh.close()

    def discard(self):
        """The index closed, and with it gone (the partial file stays: a rerun resumes from it)."""
        self.close()
        self.index.close()

    def finish(self):
        """OUTPUT: for each case of this run (Partial.case, in order) its row, with the case's index and the current
        sweep's labels (a row an earlier run wrote may have named them otherwise), written whole; the partial file
        and the index removed."""
        from ..streams import open_output

        self.close()
        found = self._sql("SELECT cases.n, cases.labels, rows.at FROM cases LEFT JOIN rows USING (fp) ORDER BY cases.n")
        with open(self.path, "rb") as src, open_output(self.output) as out:
            out.write(HEADER.encode())
            for index, labels, at in found:
                if at is None:  # every case was resumed or computed: a row of each is there
                    raise RuntimeError(f"case {index} has no row in {self.path}")
                src.seek(at)
                fields = next(csv.reader([src.readline().decode("utf-8")]))
                row = {c: parse(c, v) for c, v in zip(COLUMNS, fields)}
                row.update(json.loads(labels), case=index)
                out.write(row_line(row).encode())
        os.unlink(self.path)
        self.discard()


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
