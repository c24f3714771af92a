"""Which code made each stored result: ``studies/results/PROVENANCE.json``.

Results stored from now on name their code themselves: a study's JSON in
``_provenance`` (:func:`studies.common.provenance`), a stored run's sidecar
in ``code`` and its ``.npz`` in its result's provenance
(:mod:`varint.identity`). Files stored before that — and the figures,
tables and claims files a study writes beside its JSON — are named here by
the commit that stored them (the code of that commit is the best that can
be said for them: "code not recorded"), and by their own record where they
have one.

Run it before committing new results; ``tests/studies/test_provenance.py``
fails when a stored file is named neither by itself nor here.

Usage: ``python studies/provenance.py``
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import RESULTS  # noqa: E402

__all__ = ["MANIFEST", "stored_files", "own_record", "record_of", "build"]

MANIFEST = RESULTS / "PROVENANCE.json"
#: Not results: scratch and the manifest itself.
_SKIP = {"quick", "checkpoints"}


def stored_files(folder=RESULTS):
    """Every stored file under ``folder``, as paths relative to it."""
    folder = Path(folder)
    return sorted(p.relative_to(folder) for p in folder.rglob("*")
                  if p.is_file() and not _SKIP & set(p.relative_to(folder).parts)
                  and p != folder / MANIFEST.name)


def own_record(path):
    """The code identity a stored file records about itself (a dict with
    at least ``source``), or None."""
    path = Path(path)
    try:
        if path.suffix == ".json":
            data = json.loads(path.read_text())
            if isinstance(data, dict):
                code = (data.get("_provenance") or {}).get("code") or data.get("code")
                return code if isinstance(code, dict) and code.get("source") else None
        elif path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                if "__meta__" in z.files:
                    code = json.loads(str(z["__meta__"])).get("provenance", {}).get("code")
                    return code if code and code.get("source") else None
    except (OSError, ValueError):
        return None
    return None


def record_of(folder, rel):
    """The code record of stored file ``rel``: its own, or for the files a
    study writes beside its JSON (``<name>.claims.json``, ``<name>*.csv``,
    ``<name>*.png``, ...) that of the study JSON whose name is the longest
    prefix of the file's."""
    folder, rel = Path(folder), Path(rel)
    own = own_record(folder / rel)
    if own is not None:
        return own
    stems = sorted((p.stem for p in (folder / rel.parent).glob("*.json")
                    if rel.name.startswith(p.stem) and p.name != rel.name
                    and not p.name.endswith(".claims.json")), key=len, reverse=True)
    for stem in stems:
        found = own_record(folder / rel.parent / f"{stem}.json")
        if found is not None:
            return found
    return None


def _stored_in(path):
    """The last commit that changed ``path`` (None if it is not committed)."""
    out = subprocess.run(["git", "log", "-1", "--format=%H", "--", str(path)],
                         capture_output=True, text=True, cwd=RESULTS)
    return out.stdout.strip() or None


def build(folder=RESULTS):
    """The manifest: file -> {"code": its own record or None, "stored_in":
    the commit that last stored it or None}."""
    folder = Path(folder)
    return {str(rel): {"code": record_of(folder, rel), "stored_in": _stored_in(folder / rel)}
            for rel in stored_files(folder)}


def main():
    manifest = build()
    MANIFEST.write_text(json.dumps(
        {"note": "the code of every stored result: 'code' its own record (varint's source "
                 "digest and the git commit it ran from), else null (stored before code "
                 "identity was recorded); 'stored_in' the commit that last stored the file "
                 "(null: not committed yet; then the file must record its code itself)",
         "files": manifest}, indent=1))
    missing = [f for f, m in manifest.items() if m["code"] is None and m["stored_in"] is None]
    print(f"{len(manifest)} files; {sum(m['code'] is not None for m in manifest.values())} "
          f"record their code; {len(missing)} neither record it nor are committed"
          + ("".join(f"\n  {f}" for f in missing)))


if __name__ == "__main__":
    main()
