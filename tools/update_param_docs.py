"""Paste the generated parameter tables (specs/params.markdown_tables) into README.md and docs/ros.md.

Run after changing a node parameter: ``.venv/bin/python tools/update_param_docs.py``; test_graphs.py
fails until the documents match params.py.
"""
from pathlib import Path

from polarization_compass.specs.params import markdown_tables

ROOT = Path(__file__).resolve().parent.parent
START = "\n#### sky_simulator\n"
LAST_HEADING = "#### heading_estimator knobs"


def update(path: Path) -> bool:
    text = path.read_text()
    i = text.index(START)
    j = text.index(LAST_HEADING, i)
    lines = text[j:].split("\n")
    k = 1
    while k < len(lines) and not lines[k].startswith("|"):
        k += 1
    while k < len(lines) and lines[k].startswith("|"):
        k += 1
    end = j + len("\n".join(lines[:k])) + 1
    new = text[:i] + markdown_tables() + text[end:]
    if new != text:
        path.write_text(new)
    return new != text


if __name__ == "__main__":
    for doc in ("README.md", "docs/ros.md"):
        print(doc, "updated" if update(ROOT / doc) else "unchanged")
