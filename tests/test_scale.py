"""The pieces that keep the set-up linear in the model size (docs/performance.md §3) decide what the
slower code they replaced decided."""
import gc

import numpy as np
import pytest
import sympy as sp

from multipole.causality import _Analyser
from multipole.equations import _singular_matrix
from multipole.stages import bulk


def test_bulk_pauses_the_collector_and_restores_it():
    seen = []

    @bulk
    def stage(fail=False):
        seen.append(gc.isenabled())
        if fail:
            raise ValueError("stage failed")
        return 42

    assert gc.isenabled()
    assert stage() == 42 and seen == [False] and gc.isenabled()
    with pytest.raises(ValueError):
        stage(fail=True)
    assert gc.isenabled()
    gc.disable()
    try:
        stage()                       # nested in a paused region: leaves the collector paused
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_singular_matrix_by_rank_of_the_equilibrated_matrix():
    """Loops mix units: a regular matrix with entries from 1e-9 to 1e7 is regular (its determinant,
    computed by hand, is nonzero), and one whose third row is a combination of the first two is
    singular whatever the scales of its rows and columns."""
    regular = sp.Matrix([[1e7, 0, 1e-9], [0, 2e-9, 0], [3e-9, 0, 4e7]])
    assert 1e7 * 2e-9 * 4e7 - 1e-9 * 2e-9 * 3e-9 != 0
    assert not _singular_matrix(regular)
    rows = np.array([[1e7, 2.0, 1e-9], [3e-3, 1e5, 5e-9]])
    third = 2.0 * rows[0] - 7.0 * rows[1]
    singular = np.vstack([rows, third]) * np.array([[1e-6], [1.0], [1e8]]) * np.array([1.0, 1e-4, 1e9])
    assert _singular_matrix(sp.Matrix(singular.tolist()))
    assert _singular_matrix(sp.Matrix([[1.0, 0.0], [0.0, 0.0]]))        # a zero row


def _reference_rows_by_trial(nulls, d):
    """The earlier greedy choice: rows in weight order, each kept if ``matrix_rank`` grows."""
    weight = np.min([np.abs(N[:, :d]).max(axis=1) / max(np.abs(N).max(), 1e-300) for N in nulls], axis=0)
    rows: list = []
    for _ in range(d):
        for i in [i for i in np.argsort(-weight) if i not in rows]:
            if np.linalg.matrix_rank(nulls[0][rows + [i], :d]) == len(rows) + 1:
                rows.append(i)
                break
    return rows


@pytest.mark.parametrize("seed", range(6))
def test_reference_rows_match_the_trial_by_rank(seed):
    """Null bases with repeated and proportional rows (equations that carry the same combination):
    the one-pass choice takes the same rows as the rank test of every trial."""
    rng = np.random.default_rng(seed)
    d = 4
    base = rng.normal(size=(6, d))
    rows = [base[i] for i in range(6)] + [3.0 * base[1], -base[4], base[0] + base[2], np.zeros(d)]
    order = rng.permutation(len(rows))
    N0 = np.array(rows)[order]
    nulls = [N0, N0 * rng.uniform(0.5, 2.0, size=(len(rows), 1))]
    assert _Analyser.reference_rows(nulls, d) == _reference_rows_by_trial(nulls, d)
