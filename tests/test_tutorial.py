"""docs/tutorial.md against the script that makes it (examples/tutorial/make_tutorial.py) and its numbers.

Fast checks (no simulation): the ``magsoro ...`` command lines in the page's code blocks and the script's
COMMANDS are the same; every picture the page links exists in docs/tutorial/; every number the page quotes (each
marked ``<!--n:KEY-->`` in the Markdown source) agrees with docs/tutorial/numbers.json to the digits shown; every
line of the page's TOML excerpts is a line of a tutorial scene file.

Slow check: run the script into tmp_path and compare every command, picture and number with the committed ones.
"""

from __future__ import annotations

import importlib.util
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "tutorial.md"
DOCS_DIR = REPO / "docs" / "tutorial"
SCRIPT = REPO / "examples" / "tutorial" / "make_tutorial.py"

#: Wall times depend on the machine and its load; the page quotes them as an indication only.
INFORMATIONAL_REL = 0.5

NUMBER_MARK = re.compile(r"(-?\d+(?:\.\d+)?)<!--n:([A-Za-z0-9_]+)(\|abs)?-->")


def load_script():
    spec = importlib.util.spec_from_file_location("make_tutorial", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def code_blocks(text: str) -> list[tuple[str, list[str]]]:
    """(language, lines) of every fenced code block of a Markdown text."""
    blocks, lang, lines = [], None, []
    for line in text.splitlines():
        if line.startswith("```"):
            if lang is None:
                lang, lines = line[3:].strip(), []
            else:
                blocks.append((lang, lines))
                lang = None
        elif lang is not None:
            lines.append(line)
    assert lang is None, "docs/tutorial.md: a code block is not closed"
    return blocks


def doc_commands(text: str) -> list[str]:
    """The ``magsoro ...`` command lines of the page's shell code blocks, without trailing comments."""
    out = []
    for lang, lines in code_blocks(text):
        if lang not in ("bash", "sh", "shell", "console"):
            continue
        for line in lines:
            line = line.strip()
            if line.startswith("magsoro "):
                out.append(re.sub(r"\s+#.*$", "", line).strip())
    return out


def test_doc_commands_pictures_and_script_agree():
    """Every magsoro command of the page is run by the script, and the other way round; every picture the page
    links exists (and every picture the script makes is shown)."""
    text = DOC.read_text()
    script = load_script()
    shown = doc_commands(text)
    assert shown, "docs/tutorial.md shows no magsoro command"
    missing = [c for c in shown if c not in script.COMMANDS]
    assert not missing, f"commands in docs/tutorial.md that make_tutorial.py does not run: {missing}"
    unshown = [c for c in script.COMMANDS if c not in shown]
    assert not unshown, f"commands make_tutorial.py runs that docs/tutorial.md does not show: {unshown}"
    assert shown == list(script.COMMANDS), "docs/tutorial.md shows the commands in another order than the script"

    links = re.findall(r"!\[[^\]]*\]\((tutorial/[^)\s]+)\)", text)
    assert links, "docs/tutorial.md shows no picture"
    absent = [link for link in links if not (DOCS_DIR.parent / link).is_file()]
    assert not absent, f"pictures linked from docs/tutorial.md that do not exist: {absent}"
    linked = {Path(link).name for link in links}
    assert set(script.PICTURES) <= linked, f"pictures not shown: {set(script.PICTURES) - linked}"
    assert (DOCS_DIR / "numbers.json").is_file()


def test_doc_numbers_match_numbers_json():
    """Each marked number of the page is the numbers.json value rounded to the digits shown (wall times within
    50 %); a marker ``|abs`` means the page quotes the magnitude (and says 'below', 'slower', ...)."""
    text = re.sub(r"`[^`\n]*`", "", DOC.read_text())  # inline code may show a marker as an example
    numbers = json.loads((DOCS_DIR / "numbers.json").read_text())["numbers"]
    marks = NUMBER_MARK.findall(text)
    assert len(marks) >= 30, f"only {len(marks)} marked numbers in docs/tutorial.md"
    # a marker with no number right before it would silently check nothing
    assert text.count("<!--n:") == len(marks), "a <!--n:KEY--> marker does not follow a number"
    bad = []
    for shown, key, absolute in marks:
        if key not in numbers:
            bad.append(f"{key}: not in numbers.json")
            continue
        entry = numbers[key]
        value = abs(entry["value"]) if absolute else entry["value"]
        decimals = len(shown.split(".")[1]) if "." in shown else 0
        if entry["tolerance"].get("rel") is None:  # a wall time
            ok = abs(float(shown) - value) <= INFORMATIONAL_REL * abs(value) + 0.5 * 10**-decimals
        else:
            ok = abs(float(shown) - value) <= 0.5 * 10**-decimals * (1 + 1e-9) + 1e-12
        if not ok:
            bad.append(f"{key}: the page says {shown}, numbers.json has {entry['value']} {entry['unit']}")
    assert not bad, "docs/tutorial.md disagrees with docs/tutorial/numbers.json:\n" + "\n".join(bad)


def test_doc_toml_excerpts_are_in_the_scene_files():
    """The page's TOML excerpts are copied from the scene files, line by line."""
    script = load_script()
    lines = set()
    for name in script.SCENES:
        lines |= {line.strip() for line in (SCRIPT.parent / name).read_text().splitlines()}
    bad = [line for lang, block in code_blocks(DOC.read_text()) if lang == "toml" for line in block
           if line.strip() and line.strip() not in lines]
    assert not bad, f"TOML lines in docs/tutorial.md that no tutorial scene file has: {bad}"


def _non_blank(path: Path):
    """Raise unless the picture (every frame of a GIF) has content: several colours and some contrast."""
    import numpy as np
    from PIL import Image, ImageSequence

    with Image.open(path) as im:
        frames = [np.asarray(f.convert("RGB"), dtype=float) for f in ImageSequence.Iterator(im)]
    assert min(f.shape[0] for f in frames) >= 100 and min(f.shape[1] for f in frames) >= 100, path
    for f in frames:
        assert f.std() > 5.0, f"{path.name}: a blank frame (pixel std {f.std():.2f})"
        background = np.median(f.reshape(-1, 3), axis=0)
        drawn = np.any(np.abs(f - background) > 30, axis=2).mean()
        assert drawn > 0.01, f"{path.name}: only {drawn:.1%} of the pixels differ from the background"
    if path.suffix == ".gif":
        assert len(frames) > 10, f"{path.name}: {len(frames)} frames"
        assert np.abs(frames[0] - frames[-1]).mean() > 0.5, f"{path.name}: the first and last frames are alike"


@pytest.mark.slow
def test_tutorial_script_reproduces_commands_pictures_and_numbers(tmp_path):
    """Run the whole tutorial (about 3 minutes on 2 cores) and compare with what docs/ holds."""
    script = load_script()
    out, docs = tmp_path / "work", tmp_path / "docs"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--out", str(out), "--docs", str(docs)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=1800, check=False)
    assert proc.returncode == 0, proc.stdout[-6000:]

    records = json.loads((out / "commands.json").read_text())
    assert [r["command"] for r in records] == list(script.COMMANDS)
    assert all(r["returncode"] == 0 for r in records), records

    for name in script.PICTURES:
        assert (docs / name).is_file(), f"{name} was not written"
        _non_blank(docs / name)

    fresh = json.loads((docs / "numbers.json").read_text())["numbers"]
    committed = json.loads((DOCS_DIR / "numbers.json").read_text())["numbers"]
    assert set(fresh) == set(committed), set(fresh) ^ set(committed)
    bad = []
    for key, entry in committed.items():
        tol = entry["tolerance"]
        if tol.get("rel") is None:
            continue  # wall times
        a, b = fresh[key]["value"], entry["value"]
        if not (math.isfinite(a) and abs(a - b) <= tol["abs"] + tol["rel"] * abs(b)):
            bad.append(f"{key}: {a} now, {b} in docs/tutorial/numbers.json (tolerance {tol})")
    assert not bad, "the tutorial's numbers moved:\n" + "\n".join(bad)
