"""Labels of the plots: wrapped legend entries and the rows of the channel heatmaps."""

from __future__ import annotations

from workbench.plots.heatmap import channel_groups
from workbench.plots.timeline import wrap_label


def test_long_legend_labels_wrap_at_spec_separators_and_short_ones_stay():
    assert wrap_label("noisy (RMS)") == "noisy (RMS)"
    assert wrap_label("mssa:space=positions (RMS)") == "mssa:space=positions\n(RMS)"
    assert (
        wrap_label("ebd>ebf:positions=true,root_sigma_frames=0 (RMS)")
        == "ebd>ebf:positions=true,\nroot_sigma_frames=0\n(RMS)"
    )
    assert wrap_label("x" * 30) == "x" * 30  # nowhere to break: whole


def test_heatmap_rows_are_grouped_by_joint_in_both_layouts():
    names = ["Hips", "Spine", "Head"]
    angles = channel_groups(names, 3 + 3 * 3)
    assert angles[0] == ("root position", 0, 3, None) and angles[-1] == ("Head", 9, 12, 2)
    positions = channel_groups(names, 3 * 3)
    assert positions[0] == ("Hips", 0, 3, 0) and positions[-1] == ("Head", 6, 9, 2)
    assert channel_groups(names, 5) == [("channels", 0, 5, None)]
