"""Bit checks of a tree against a reference tree: the per-case hashes that
``studies/fingerprints.py`` prints (``label hash (seconds)``), read from the
logs of runs on each tree (both on this machine, fresh caches), compared
case by case; stored as ``suite_bits_<--name>.json``.

A run cut short still counts the cases it printed: only the cases both
logs hold are compared, and the ones only one holds are listed.

Usage: ``python studies/suite_bits.py --pair LABEL REFERENCE_LOG NEW_LOG
[--pair ...] [--note TEXT] [--name NAME] [--out DIR]``
"""

from __future__ import annotations

import re
from pathlib import Path

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.suite_bits
    from .common import parse_args, save_json

_CASE = re.compile(r"^(\S+)\s+([0-9a-f]{16})\s+\(")


def hashes(log):
    """{case label: hash} of the lines of a fingerprints log."""
    out = {}
    for line in Path(log).read_text().splitlines():
        found = _CASE.match(line)
        if found:
            out[found.group(1)] = found.group(2)
    return out


def compare(reference, new):
    """The cases both hold, those equal and those changed, and the cases
    only one holds."""
    both = sorted(set(reference) & set(new))
    return {"cases": len(both), "equal": sum(reference[k] == new[k] for k in both),
            "changed": [k for k in both if reference[k] != new[k]],
            "only_reference": sorted(set(reference) - set(new)),
            "only_new": sorted(set(new) - set(reference)),
            "hashes": {k: [reference[k], new[k]] for k in both}}


def main(argv=None):
    def extra(parser):
        parser.add_argument("--pair", nargs=3, action="append", required=True,
                            metavar=("LABEL", "REFERENCE_LOG", "NEW_LOG"))
        parser.add_argument("--note", default=None)
        parser.add_argument("--name", default="check")

    args = parse_args(__doc__.splitlines()[0], argv, extra=extra)
    table = {label: compare(hashes(ref), hashes(new)) for label, ref, new in args.pair}
    for label, c in table.items():
        print(f"{label}: {c['cases']} cases, {c['equal']} equal, {len(c['changed'])} changed"
              + (f" ({', '.join(c['changed'])})" if c["changed"] else ""))
    save_json(args.out, f"suite_bits_{args.name}", {"pairs": table, "note": args.note})
    return table


if __name__ == "__main__":
    main()
