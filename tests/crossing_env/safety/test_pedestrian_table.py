"""Tests of crossing_env.safety.pedestrian_table (per-pedestrian episode state keyed by id)."""

from __future__ import annotations

import math

import numpy as np

from crossing_env.safety.pedestrian_table import NO_STATE, PedestrianTable


def test_rows_are_added_sorted_with_their_fill_values() -> None:
    tab = PedestrianTable()
    rows = tab.rows(np.array([7, 3]))
    assert tab.ids.tolist() == [3, 7] and rows.tolist() == [1, 0]
    tab.last_exit[rows[0]] = 2.0  # id 7
    rows = tab.rows(np.array([5, 7]))
    assert tab.ids.tolist() == [3, 5, 7] and rows.tolist() == [1, 2]
    assert tab.last_exit.tolist() == [-math.inf, -math.inf, 2.0]
    assert math.isnan(tab.wait_start[1]) and tab.prev_state[1] == NO_STATE and not tab.in_ca[1]
