"""Writes the README's option table from the option schema (addon/atlas_defrag/options.py).

    PYTHONPATH=addon python3 tools/options_doc.py          # rewrites README.md
    PYTHONPATH=addon python3 tools/options_doc.py --check  # exit 1 if it is stale

python_tests/test_options.py fails when the table is stale.
"""
from __future__ import annotations

import sys
from pathlib import Path

from atlas_defrag import options

README = Path(__file__).resolve().parent.parent / "README.md"
BEGIN = "<!-- BEGIN options: written by tools/options_doc.py from addon/atlas_defrag/options.py -->"
END = "<!-- END options -->"


def table() -> str:
    rows = ["| option | values | default | what it does | dialog | batch and CLI |",
            "|---|---|---|---|---|---|"]
    for o in options.SCHEMA:
        values = options.range_text(o) + (f" {o.unit}" if o.unit else "")
        what = o.help + (f"; 0: {o.automatic}" if o.automatic else "")
        rows.append(f"| `{o.name}` | {values} | `{o.default!r}` | {what} | {o.label} | `{options.flag(o)}` |")
    return "\n".join(rows)


def update(text: str) -> str:
    """text with the part between the markers replaced by the current table."""
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    return text[:start] + "\n" + table() + "\n" + text[end:]


def main(argv) -> int:
    text = README.read_text()
    current = update(text)
    if "--check" in argv:
        if current != text:
            print(f"{README} has a stale option table: run tools/options_doc.py", file=sys.stderr)
            return 1
        return 0
    README.write_text(current)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
