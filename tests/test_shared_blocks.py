"""The blocks every script copies (env, SAC, evaluation, results, checkpoint, actor io, demonstrations)
must stay identical across scripts: a fix made in one copy and not the others fails here."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^# --- shared: (?P<name>[\w ]+) ---\n(?P<body>.*?)^# --- end shared: (?P=name) ---$", re.S | re.M)
# expert.py holds the core blocks; every script holds those it needs
REFERENCE = "expert.py"
EXPECTED = {"env", "actor", "sac", "evaluation", "results", "checkpoint", "actor io", "demonstrations"}


def blocks(path: Path) -> dict:
    text = path.read_text()
    found = {m["name"]: m["body"] for m in BLOCK.finditer(text)}
    opened = re.findall(r"^# --- shared: ([\w ]+) ---$", text, re.M)
    assert sorted(opened) == sorted(found), f"{path.name}: a shared block is opened but not closed: {opened}"
    return found


def test_reference_has_every_block():
    assert set(blocks(ROOT / REFERENCE)) == EXPECTED


def test_copies_are_identical():
    """Every block, in every script that holds it, is the same text (expert.py's where it has one)."""
    seen = {}
    for path in [ROOT / REFERENCE] + [p for p in sorted(ROOT.glob("*.py")) if p.name != REFERENCE]:
        for name, body in blocks(path).items():
            first, first_body = seen.setdefault(name, (path.name, body))
            assert body == first_body, f"shared block '{name}' of {path.name} differs from {first}'s"


def test_block_pattern_detects_drift(tmp_path):
    """The checker itself: a changed line inside a block is seen."""
    body = "x = 1\n"
    a = tmp_path / "a.py"
    a.write_text(f"# --- shared: sac ---\n{body}# --- end shared: sac ---\n")
    b = tmp_path / "b.py"
    b.write_text("# --- shared: sac ---\nx = 2\n# --- end shared: sac ---\n")
    assert blocks(a)["sac"] == body and blocks(a)["sac"] != blocks(b)["sac"]
