"""The tuning explorers of chapters 03 and 09: the static figure's verdicts and the sliders' wiring."""
import matplotlib.pyplot as plt
import numpy as np
import pytest

from kalman_course.chapters import explorers
from kalman_course.data import cv_target, load_kitti

DT, SIGMA_A, SIGMA = 0.5, 0.4, 2.5          # σ ≠ 1 so that σ and σ² cannot be confused


@pytest.fixture(scope="module")
def runs():
    return [cv_target(80, DT, SIGMA_A, SIGMA, seed=seed, dim=1) for seed in range(40)]


def _cv_title(runs, sigma_a, sigma):
    fig = explorers.cv_tuning_figure(runs, [0.0, 1.0], np.diag([SIGMA**2, 1.0]), DT, sigma_a, sigma)
    title = fig._suptitle.get_text()
    plt.close(fig)
    return title


def _verdicts(title):
    # "mean NEES 2.01 (band 1.80–2.20, consistent), mean NIS ..." -> {"NEES": "consistent", "NIS": ...}
    found = {}
    for part in title.split("mean ")[1:]:
        name = part.split()[0]
        found[name] = part.split(", ")[1].split(")")[0]
    return found


def test_cv_figure_verdicts_follow_the_filter_setting(runs):
    # the title is the lesson: the true setting passes, a σ ten times too small or large is named
    assert _verdicts(_cv_title(runs, SIGMA_A, SIGMA)) == {"NEES": "consistent", "NIS": "consistent"}
    assert _verdicts(_cv_title(runs, SIGMA_A, SIGMA / 10))["NIS"] == "overconfident"
    assert _verdicts(_cv_title(runs, SIGMA_A, SIGMA * 10))["NIS"] == "underconfident"
    assert _verdicts(_cv_title(runs, SIGMA_A / 30, SIGMA))["NEES"] == "overconfident"


def test_cv_figure_says_the_runs_are_simulated(runs):
    assert _cv_title(runs, SIGMA_A, SIGMA).startswith("simulated CV target")


def test_cv_figure_needs_runs():
    with pytest.raises(ValueError, match="runs"):
        explorers.cv_tuning_figure([], [0.0, 1.0], np.eye(2), DT, SIGMA_A, SIGMA)


def _recording_draw(calls):
    def draw(**values):
        calls.append(values)
        fig, ax = plt.subplots()
        ax.plot([0, 1], [0, values["a"]])
        return fig
    return draw


def test_slider_explorer_redraws_with_the_moved_value():
    import ipywidgets

    calls = []
    box = explorers.slider_explorer(_recording_draw(calls), {"a": ("a", 1.0, 0.1, 10.0), "b": ("b", 2.0, 1.0, 4.0)})
    sliders = [w for w in box.children if isinstance(w, ipywidgets.FloatLogSlider)]
    outputs = [w for w in box.children if isinstance(w, ipywidgets.Output)]
    assert len(sliders) == 2 and len(outputs) == 1
    assert calls == [{"a": 1.0, "b": 2.0}]                  # drawn once at the start values
    a = sliders[0]
    assert (a.min, a.max) == pytest.approx((-1.0, 1.0))     # log10 of the range
    a.value = 3.0
    assert calls[-1] == {"a": pytest.approx(3.0), "b": 2.0}
    assert plt.get_fignums() == []                          # every drawn figure is closed


@pytest.mark.parametrize("spec", [("a", 1.0, 0.0, 10.0), ("a", 20.0, 0.1, 10.0), ("a", 1.0, 5.0, 2.0)],
                         ids=["zero min", "value above max", "min above max"])
def test_slider_explorer_rejects_a_range_a_log_slider_cannot_show(spec):
    with pytest.raises(ValueError, match=r"sliders\['a'\]"):
        explorers.slider_explorer(_recording_draw([]), {"a": spec})


def test_cv_explorer_ranges_bracket_the_given_setting(runs):
    box = explorers.cv_tuning_explorer(runs, [0.0, 1.0], np.diag([SIGMA**2, 1.0]), DT, SIGMA_A, SIGMA)
    values = [w.value for w in box.children[:2]]
    assert values == pytest.approx([SIGMA_A, SIGMA])
    plt.close("all")


def test_eskf_figure_names_real_and_simulated_inputs_and_moves_with_q():
    cruise = load_kitti("cruise")
    titles = {}
    for q in (1.0, 0.01):
        fig = explorers.eskf_tuning_figure(cruise, q, 1.0)
        titles[q] = fig._suptitle.get_text()
        plt.close(fig)
    assert titles[1.0].startswith("real IMU and truth, simulated lidar poses")
    # Q a hundred times too small: the pose NEES says overconfident (chapter 09's table)
    assert _verdicts(titles[0.01])["pose"] == "overconfident"
    assert titles[1.0] != titles[0.01]
