"""`python <script> --help` reads well for someone who has never opened the file: it starts with what the script is
and how to start it, prints each default once, shows every field's docstring as whole sentences, points nowhere
into the header by number, and words the common flags the same way in every script."""

import ast
import contextlib
import importlib
import io
import re

import pytest
import tyro
from tyro import _strings

from conftest import ROOT

SCRIPTS = ["rile", "gail", "airl", "gaifo", "iqlearn", "drail_disc", "bc", "bco", "expert"]


def render_help(name: str, monkeypatch) -> str:
    monkeypatch.setenv("COLUMNS", "200")
    module = importlib.import_module(name)
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        tyro.cli(module.Args, args=["--help"])
    return out.getvalue()


def field_docstrings(name: str) -> dict:
    """{field: the raw docstring below it} of `class Args`, read from the source as tyro reads it."""
    tree = ast.parse((ROOT / f"{name}.py").read_text())
    args = next(node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "Args")
    docs = {}
    for field, doc in zip(args.body, args.body[1:]):
        if isinstance(field, ast.AnnAssign) and isinstance(doc, ast.Expr) and isinstance(doc.value, ast.Constant):
            docs[field.target.id] = doc.value.value
    return docs


def option_entries(help_text: str) -> list:
    """The help's option entries, each a flag's line and its wrapped continuation lines joined."""
    entries = []
    for line in help_text.splitlines():
        content = line.strip().strip("│|").strip()
        if content.startswith("-"):
            entries.append(content)
        elif entries and content and not content.startswith(("╰", "╭", "---", "───")):
            entries[-1] += " " + content
    return entries


@pytest.mark.parametrize("name", SCRIPTS)
def test_help_reads_whole(name, monkeypatch):
    help_text = render_help(name, monkeypatch)
    before_options = help_text.split("-h, --help")[0].splitlines()
    description = [line for line in before_options[1:] if line.strip() and "options" not in line and "---" not in line
                   and not line.strip().startswith(("╭", "│"))]
    assert description and f"python {name}.py" in help_text.split("-h, --help")[0], \
        f"{name}.py --help has no description with a command to start it"
    twice = [entry for entry in option_entries(help_text) if entry.count("(default:") > 1]
    assert not twice, f"{name}.py --help prints a default twice: {twice}"
    pointers = re.findall(r"[^\n]*(?:choice \d|\bheader\b)[^\n]*", help_text, re.I)
    assert not pointers, f"{name}.py --help points into the header: {pointers}"
    docs = field_docstrings(name)
    assert docs, f"no field docstrings found in {name}.py's Args"
    broken = {field: doc for field, doc in docs.items() if "\n" in _strings.remove_single_line_breaks(doc)}
    assert not broken, f"{name}.py: tyro shows these docstrings with a hard line break: {broken}"


def test_common_fields_are_worded_the_same_in_every_script():
    """The common block (exp_name ... threads) says the same thing everywhere; a field differs only where the script
    does something different (what it saves, what it counts, what else a resume takes from the command line)."""
    differs = {"save_model": set(SCRIPTS), "checkpoint_freq": {"bc"}, "resume": {"expert"}}
    common = ["exp_name", "seed", "torch_deterministic", "cuda", "track", "wandb_project_name", "wandb_entity",
              "capture_video", "save_model", "run_name", "resume", "checkpoint_freq", "threads"]
    reference = field_docstrings("rile")
    for name in SCRIPTS:
        docs = field_docstrings(name)
        for field in common:
            if field in docs and name not in differs.get(field, ()):
                assert docs[field] == reference[field], f"{name}.py words --{field.replace('_', '-')} differently"
