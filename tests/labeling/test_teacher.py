"""What the session teaches stage 2: the terrain its blend is sure of over an unlabelled stretch."""

from __future__ import annotations

import numpy as np

import labeling


def test_a_stretch_is_taught_where_the_blend_is_sure_of_one_terrain() -> None:
    sure = np.tile([0.4, 0.6], (100, 1))  # (T, K) every step class 1
    torn = np.tile([[0.6, 0.4], [0.4, 0.6]], (50, 1))  # half and half
    probs = [sure, torn, None]
    stretches = [(0, 0, 50), (1, 0, 50), (2, 0, 50), (0, 10, 10)]
    assert labeling.taught_terrains(probs, stretches).tolist() == [1, -1, -1, -1]  # unsure, unscored, empty: none
    sure[:3] = [0.9, 0.1]  # 3 of the first 50 steps another class: 94 % agree
    assert labeling.taught_terrains(probs, stretches, sure=0.96).tolist() == [-1, -1, -1, -1]
    assert labeling.taught_terrains(probs, stretches, sure=0.9).tolist() == [1, -1, -1, -1]


def test_the_taught_class_is_counted_in_the_fits_classes_not_the_blends() -> None:
    blend = np.tile([0.02, 0.03, 0.95], (20, 1))  # the blend's columns: a, b, c
    # the fit knows c and a (in that order) and a terrain the blend has no column for
    got = labeling.taught_terrains([blend], [(0, 0, 20)], columns=[2, 0, -1])
    assert got.tolist() == [0]
    assert labeling.taught_terrains([blend], [(0, 0, 20)], columns=[-1, 0, 1]).tolist() == [-1]  # c left out
