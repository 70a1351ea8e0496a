"""msk.report.svg: nice ticks, curves split at gaps, every text escaped."""

from __future__ import annotations

import numpy as np

from msk.report import svg


def test_nice_ticks_are_round_and_cover_the_range():
    assert svg.nice_ticks(0.0, 100.0) == [0.0, 25.0, 50.0, 75.0, 100.0]
    t = svg.nice_ticks(-0.73, 1.41)
    assert t[0] >= -0.73 and t[-1] <= 1.41 and len(t) >= 4
    steps = np.diff(t)
    np.testing.assert_allclose(steps, steps[0])
    assert steps[0] in (0.5, 0.25)


def test_a_gap_splits_the_curve_and_labels_are_escaped():
    p = svg.Panel(title="<script>x</script>", xlabel="a & b", ylabel="y")
    y = np.array([0.0, 1.0, np.nan, 2.0, 3.0])
    p.line(np.arange(5.0), y, "#000", label='"><iframe>')
    text = svg.grid([p], 1, label="t")
    assert text is not None
    assert text.count("<polyline") == 2
    assert "<script>" not in text and "&lt;script&gt;" in text and "&lt;iframe" in text
    assert "a &amp; b" in text


def test_no_curve_no_figure():
    assert svg.grid([svg.Panel(title="empty"), None], 2, label="t") is None
