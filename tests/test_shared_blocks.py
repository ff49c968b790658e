"""The blocks the scripts copy (env, actor, SAC, demonstrations, absorbing states, evaluation, the run's
plumbing, the discriminator, GAIL's and RILe's updates) must stay identical across scripts, and appear in one
canonical order: the method's blocks first, then the plumbing. A fix made in one copy and not the others
fails here; `python tests/test_shared_blocks.py` copies gail.py's blocks into the others."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^# --- shared: (?P<name>[\w ]+) ---\n(?P<body>.*?)^# --- end shared: (?P=name) ---$", re.S | re.M)
# gail.py holds every plumbing block; every script holds those it needs, in this order
REFERENCE = "gail.py"
ORDER = ["rile", "discriminator", "gail", "reward measures", "frozen reward", "absorbing", "env", "actor", "critic", "sac",
         "buffer", "demonstrations", "expert data", "evaluation", "run"]
SCRIPTS = ["expert.py", "gail.py", "rile.py", "airl.py", "gaifo.py", "iqlearn.py", "drail_disc.py", "bc.py", "bco.py"]


def blocks(path: Path) -> dict:
    text = path.read_text()
    found = {m["name"]: m["body"] for m in BLOCK.finditer(text)}
    opened = re.findall(r"^# --- shared: ([\w ]+) ---$", text, re.M)
    assert sorted(opened) == sorted(found), f"{path.name}: a shared block is opened but not closed: {opened}"
    return found


def test_reference_has_every_plumbing_block():
    assert set(blocks(ROOT / REFERENCE)) == set(ORDER) - {"rile"}


def test_copies_are_identical():
    """Every block, in every script that holds it, is the same text (gail.py's where it has one)."""
    seen = {}
    for name in [REFERENCE] + [s for s in SCRIPTS if s != REFERENCE]:
        for block, body in blocks(ROOT / name).items():
            first, first_body = seen.setdefault(block, (name, body))
            assert body == first_body, f"shared block '{block}' of {name} differs from {first}'s"


def test_blocks_appear_in_the_canonical_order():
    for name in SCRIPTS:
        found = list(blocks(ROOT / name))
        assert set(found) <= set(ORDER), f"{name}: unknown shared blocks {set(found) - set(ORDER)}"
        assert found == sorted(found, key=ORDER.index), f"{name}: shared blocks in the order {found}, not {ORDER}"


def test_block_pattern_detects_drift(tmp_path):
    """The checker itself: a changed line inside a block is seen."""
    body = "x = 1\n"
    a = tmp_path / "a.py"
    a.write_text(f"# --- shared: sac ---\n{body}# --- end shared: sac ---\n")
    b = tmp_path / "b.py"
    b.write_text("# --- shared: sac ---\nx = 2\n# --- end shared: sac ---\n")
    assert blocks(a)["sac"] == body and blocks(a)["sac"] != blocks(b)["sac"]


if __name__ == "__main__":  # python tests/test_shared_blocks.py: copy gail.py's blocks into every script that holds them
    reference = {m["name"]: m.group(0) for m in BLOCK.finditer((ROOT / REFERENCE).read_text())}
    for name in SCRIPTS:
        path = ROOT / name
        text = path.read_text()
        synced = BLOCK.sub(lambda m: reference.get(m["name"], m.group(0)), text)
        if synced != text:
            path.write_text(synced)
            print(f"synced {name}")
