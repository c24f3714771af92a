"""Every stored result names its code: by itself, or in
studies/results/PROVENANCE.json by the commit that stored it."""

import json

import numpy as np

from studies import provenance
from studies.common import RESULTS


def test_every_stored_result_names_its_code():
    listed = json.loads(provenance.MANIFEST.read_text())["files"]
    nameless = [str(f) for f in provenance.stored_files()
                if provenance.record_of(RESULTS, f) is None
                and not (listed.get(str(f)) or {}).get("stored_in")]
    assert nameless == [], "run python studies/provenance.py and commit"


def test_a_record_is_read_from_a_study_json_a_sidecar_and_a_result(tmp_path):
    """The three places code is recorded, and nothing made up where there
    is none."""
    import varint

    code = {"source": "a" * 64, "commit": None, "modified": None}
    (tmp_path / "study.json").write_text(json.dumps({"_provenance": {"code": code}}))
    (tmp_path / "run.json").write_text(json.dumps({"cpu": 1.0, "code": code}))
    (tmp_path / "old.json").write_text(json.dumps({"cpu": 1.0}))
    r = varint.lyapunov_spectrum(*varint.paper_orbit("R1"), 1.0, tau=0.05)
    r.save(tmp_path / "r.npz")
    np.savez(tmp_path / "plain.npz", x=np.zeros(2))
    assert provenance.own_record(tmp_path / "study.json") == code
    assert provenance.own_record(tmp_path / "run.json") == code
    assert provenance.own_record(tmp_path / "r.npz") == r.provenance.code
    assert provenance.own_record(tmp_path / "old.json") is None
    assert provenance.own_record(tmp_path / "plain.npz") is None
    # A study's claims and tables beside its JSON share its record.
    (tmp_path / "study.claims.json").write_text("[]")
    (tmp_path / "study_rows.csv").write_text("a\n")
    assert provenance.record_of(tmp_path, "study.claims.json") == code
    assert provenance.record_of(tmp_path, "study_rows.csv") == code
    assert provenance.record_of(tmp_path, "old.csv") is None
