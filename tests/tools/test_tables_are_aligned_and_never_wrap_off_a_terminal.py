"""The printed tables of the benchmarks and of ``cassie report`` (rich): one line per row however
wide, columns aligned, cells printed as given (``[ms]`` is not markup), no styles or trailing
blanks when the output is a file or a pipe."""

from __future__ import annotations

import io

from tools.benchmarks.common import print_columns, print_table
from tools.report import print_loops


def test_a_wide_table_keeps_one_line_per_row_with_its_cells_as_given() -> None:
    out = io.StringIO()
    long_label = "S3 per-stage time median / p99 / max [ms] " + "x" * 150
    print_table("S3 per-stage time (all sequences)",
                [(long_label, "1.00 / 2.00 / 3.00"), ("frames", 300), ("ratio", 0.123456)],
                out=out)
    lines = out.getvalue().splitlines()
    assert lines[:3] == ["", "S3 per-stage time (all sequences)",
                         "---------------------------------"]
    rows = lines[3:]
    assert len(rows) == 3 and rows[0].startswith(long_label)
    assert all(line == line.rstrip() and "\x1b" not in line for line in rows)
    # the values start in one column; floats are shown to 4 significant digits
    assert {r.index(v) for r, v in zip(rows, ("1.00 /", "300", "0.1235"), strict=True)} == {
        len(long_label) + 2}


def test_columns_align_right_under_a_header_and_fall_back_to_dashes_without_utf8() -> None:
    raw = io.BytesIO()
    out = io.TextIOWrapper(raw, encoding="ascii")
    print_columns(["loop", "Hz", "budget"], [["ticker/ticker", "200.0", "ok"],
                                            ["sim/sim", "2000.0", None]], out, justify="lrl")
    out.flush()
    head, rule, *rows = raw.getvalue().decode("ascii").splitlines()
    assert set(rule) == {"-"} and head.split() == ["loop", "Hz", "budget"]
    assert rows[0].index("200.0") + len("200.0") == rows[1].index("2000.0") + len("2000.0")
    assert rows[1].split() == ["sim/sim", "2000.0"]  # a None cell is blank


def test_the_reports_loops_table_names_every_loop_on_its_own_line() -> None:
    row = {"rate_hz": 2000.0, "exec_p50_ms": 0.07, "exec_p99_ms": 0.2, "exec_p999_ms": 0.4,
           "exec_max_ms": 1.5, "cpu_p50_ms": 0.06, "lateness_p99_ms": 0.1,
           "deadline_misses": 3, "miss_ratio": 0.0015, "within_budget": False,
           "budget": "exec_p99_ms<=0.15"}
    out = io.StringIO()
    print_loops({"osc/osc": row, "a_very_long_process_name/its_loop": {**row, "budget": ""}},
                out)
    lines = out.getvalue().splitlines()
    assert lines[1].startswith("Loops (") and lines[3].split()[:2] == ["loop", "Hz"]
    osc = next(line for line in lines if line.startswith("osc/osc"))
    assert osc.split()[1:] == ["2000.0", "0.070", "0.200", "0.400", "1.50", "0.060", "0.100",
                               "3", "0.150", "exec_p99_ms<=0.15", "OVER"]
    assert any(line.startswith("a_very_long_process_name/its_loop ") for line in lines)
