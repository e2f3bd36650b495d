"""rbody.engine.memory: views numba does not count are the arrays they view."""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.memory import unowned


@njit(cache=True)
def _write_through(array, value):
    view = unowned(array)
    view[...] = value  # every element, through the view
    return view.shape, view.sum()


@njit(cache=True)
def _row_through(matrix, row):
    view = unowned(matrix)
    view[row, :] = -1.0
    return view[row].sum(), view.shape


def test_an_unowned_view_writes_and_reads_the_array_it_views():
    vector = np.arange(5.0)
    shape, total = _write_through(vector, 2.5)
    assert shape == (5,)
    assert total == 12.5
    np.testing.assert_array_equal(vector, np.full(5, 2.5))  # the original, not a copy, was written


def test_an_unowned_view_of_a_matrix_keeps_its_shape_and_rows():
    matrix = np.arange(12.0).reshape(3, 4)
    expected = matrix.copy()
    expected[1] = -1.0
    total, shape = _row_through(matrix, 1)
    assert shape == (3, 4)
    assert total == -4.0
    np.testing.assert_array_equal(matrix, expected)  # row 1 alone changed, in place
