"""scripts/ncu_stalls.py: stall-reason shares and the busiest instructions of an ncu source-page export."""

from __future__ import annotations

import gzip
from pathlib import Path

import pytest
from scriptload import load_script

ns = load_script("ncu_stalls")

HEADER = '"Address","Source","Warp Stall Sampling (All Samples)","stall_wait","stall_barrier","stall_wait (Not Issued)"'
ROWS = [
    '"0x10","  FFMA R1, R2, R3, R4","6","4","2","4"',
    '"0x20","  SYNCS.PHASECHK.TRANS64.TRYWAIT P0, [R5], R6","3","0","3","0"',
    '"0x30","  NOP","0","0","0","0"',
]


def _export(path: Path, gz: bool = False) -> Path:
    text = "\n".join(['"Kernel Name","k_forward",', HEADER, *ROWS]) + "\n"
    if gz:
        with gzip.open(path, "wt") as f:
            f.write(text)
    else:
        path.write_text(text)
    return path


@pytest.mark.parametrize("gz", [False, True])
def test_shares_and_top(tmp_path: Path, gz: bool) -> None:
    kernel, rows = ns.read_sass(_export(tmp_path / ("s.csv.gz" if gz else "s.csv"), gz))
    assert kernel == "k_forward" and len(rows) == 3
    total, shares = ns.stall_shares(rows)
    assert total == 9
    assert shares == [("wait", 4, pytest.approx(4 / 9)), ("barrier", 5, pytest.approx(5 / 9))][::-1]
    top = ns.top_instructions(rows, 2)
    assert [(a, n) for a, _, n, _ in top] == [("0x10", 6), ("0x20", 3)]
    assert top[0][1] == "FFMA R1, R2, R3, R4" and top[0][3] == "wait 4, barrier 2"


def test_markdown_and_refusals(tmp_path: Path) -> None:
    md = tmp_path / "out" / "stalls.md"
    assert ns.main([str(_export(tmp_path / "s.csv")), "--top", "1", "--markdown", str(md)]) == 0
    text = md.read_text()
    assert "| barrier | 5 | 55.6% |" in text and "| 0x10 | `FFMA R1, R2, R3, R4` | 6 | wait 4, barrier 2 |" in text
    for name, text in [
        ("no_kernel.csv", '"Address","Source"\n'),
        ("short_row.csv", '"Kernel Name","k",\n' + HEADER + '\n"0x10","NOP","1"\n'),
        ("not_a_count.csv", '"Kernel Name","k",\n' + HEADER + '\n"0x10","NOP","many","0","0","0"\n'),
    ]:
        bad = tmp_path / name
        bad.write_text(text)
        with pytest.raises(SystemExit) as exc:
            ns.main([str(bad)])
        assert exc.value.code == 2


def test_thousands_separators() -> None:
    assert ns._count("1,234") == 1234 and ns._count("-") == 0 and ns._count("") == 0


def test_against_another_launch_of_the_same_code(tmp_path: Path) -> None:
    """The instructions that grew most from another export, matched by their offset from the kernel's first one (the
    two launches' addresses differ, as between two processes), the totals and a span's samples; another code or a
    span without a second export is refused."""
    other = tmp_path / "other.csv"
    other.write_text("\n".join(['"Kernel Name","k_forward",', HEADER,
                                '"0x110","  FFMA R1, R2, R3, R4","5","4","1","4"',
                                '"0x120","  SYNCS.PHASECHK.TRANS64.TRYWAIT P0, [R5], R6","1","0","1","0"',
                                '"0x130","  NOP","0","0","0","0"']) + "\n")  # fmt: skip
    _, rows = ns.read_sass(_export(tmp_path / "s.csv"))
    _, there = ns.read_sass(other)
    more, grown = ns.grown_instructions(rows, there, 2)
    assert more == 3
    assert [(o, n, m) for o, _, n, m, _ in grown] == [("0x10", 3, 1), ("0x0", 6, 5)]
    assert ns.span_samples(rows, 0x0, 0x10) == 9 and ns.span_samples(there, 0x10, 0x20) == 1
    md = tmp_path / "cmp.md"
    argv = [str(tmp_path / "s.csv"), "--against", str(other), "--span", "0x0", "0x10", "--markdown", str(md)]
    assert ns.main(argv) == 0
    text = md.read_text()
    assert "+3 samples in all" in text and "| 0x10 | `SYNCS" in text
    assert "Offsets 0x0..0x10: 9 samples, 6 there (+3)." in text
    changed = tmp_path / "changed.csv"
    changed.write_text(other.read_text().replace("NOP", "EXIT"))
    for argv in ([str(tmp_path / "s.csv"), "--against", str(changed)], [str(tmp_path / "s.csv"), "--span", "0", "1"]):
        with pytest.raises(SystemExit) as exc:
            ns.main(argv)
        assert exc.value.code == 2
