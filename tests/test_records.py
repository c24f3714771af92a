"""varint.records: recorded outputs kept in blocks, read as one list."""

import numpy as np

from varint.records import Records


def _rec(j, m=3):
    return {"value": np.full(m, float(j)), "pair": np.arange(2 * m).reshape(m, 2) + 10 * j}


def test_blocks_and_single_outputs_read_as_one_series():
    r = Records([_rec(0), _rec(1)])
    block = {"value": np.array([np.full(3, 2.0), np.full(3, 3.0), np.full(3, 4.0)]),
             "pair": np.stack([_rec(j)["pair"] for j in (2, 3, 4)])}
    r.extend(block, 3)
    r.append(_rec(5))
    r.extend({}, 0)                    # a chunk without outputs
    assert len(r) == 6
    stacked = r.stacked()
    assert stacked["value"].shape == (6, 3) and stacked["pair"].shape == (6, 3, 2)
    assert np.array_equal(stacked["value"][:, 0], np.arange(6.0))
    for j, rec in enumerate(r):
        assert np.array_equal(rec["pair"], _rec(j)["pair"])
    # Joined once; later outputs are added to the joined block.
    r.append(_rec(6))
    assert np.array_equal(r.stacked()["value"][:, 1], np.arange(7.0))


def test_round_trip_through_stacked_arrays():
    r = Records([_rec(j) for j in range(4)])
    back = Records.from_stacked(r.stacked(), len(r))
    assert len(back) == 4
    for a, b in zip(r, back, strict=True):
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    assert Records().stacked() == {} and len(Records.from_stacked({}, 0)) == 0
