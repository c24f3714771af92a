"""The outputs a run has recorded so far.

A run records, at each output time, a dict of per-orbit arrays (the
indicator's fields, energy errors …). A batched run reads hundreds of outputs
at once from its snapshots (:func:`varint.driver.drive`); :class:`Records`
keeps each such chunk as one block (arrays with a leading output axis)
instead of splitting it into per-output dicts that are stacked again at the
end, so many outputs cost no more than the steps between them.
"""

import numpy as np

__all__ = ["Records"]


class Records:
    """Recorded outputs, in order, held as blocks of consecutive outputs.

    Parameters
    ----------
    records : iterable of dict, optional
        Per-output records to start with (one dict of arrays per output).

    Notes
    -----
    ``len`` is the number of outputs; iterating gives one dict per output
    (views into the blocks), so code that treats the records as a list of
    dicts keeps working.
    """

    def __init__(self, records=()):
        self._blocks = []
        self._n = 0
        for rec in records:
            self.append(rec)

    @classmethod
    def from_stacked(cls, stacked, n):
        """Records of ``n`` outputs from arrays with a leading output axis."""
        out = cls()
        if n:
            out.extend({key: np.asarray(arr) for key, arr in stacked.items()}, n)
        return out

    def append(self, rec):
        """Add the record of one output."""
        self.extend({key: np.asarray(arr)[None] for key, arr in rec.items()}, 1)

    def extend(self, block, n):
        """Add ``n`` consecutive outputs held in ``block`` (arrays with a
        leading axis of length ``n``)."""
        if n:
            self._blocks.append((n, block))
            self._n += n

    def __len__(self):
        return self._n

    def __iter__(self):
        for n, block in self._blocks:
            for j in range(n):
                yield {key: arr[j] for key, arr in block.items()}

    def blocks(self):
        """``(first, block)`` per block, in order: ``block`` holds outputs
        ``first`` … ``first + n − 1`` (arrays with a leading output axis of
        length n), not copied."""
        first = 0
        for n, block in self._blocks:
            yield first, block
            first += n

    def stacked(self):
        """Dict of arrays of shape (outputs, ...), empty when nothing has
        been recorded. The blocks are joined once and kept joined, so a
        run that checkpoints often does not join them again each time."""
        if not self._blocks:
            return {}
        if len(self._blocks) > 1:
            keys = self._blocks[0][1]
            self._blocks = [(self._n, {key: np.concatenate([b[key] for _, b in self._blocks])
                                       for key in keys})]
        return dict(self._blocks[0][1])
