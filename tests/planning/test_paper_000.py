"""Paper 000, Table 3: the five path planners on the toy scene, 15 seeds each.

The toy scene is section 4.3's (a 100 mm cube, start [1, 1, 1], goal [100, 100, 100], five
spheres; the paper does not print where, ours are tests/planning/test_path_planners.py's
layout 0). Table 3 prints, per algorithm, the best and the mean path over its runs:

=================== ======= ======= ========
algorithm            best    mean    time s
=================== ======= ======= ========
improved wolf pack   66.731  66.863  156.251
basic wolf pack      68.315  69.561  162.561
ACA                 104.516 106.256   42.591
GA                   75.261  76.163   39.739
AFSA                 86.631  89.901   38.517
=================== ======= ======= ========

(its "m" on a 100 mm scene, and lengths below the 171.5 mm straight line: only the order and
the ratios can be compared). What the paper claims from it: the improved wolf pack plans
shorter paths than the basic one, best and mean, and the shortest of the five.

Budget: every algorithm runs with the paper's parameters (Table 2, section 4.3) except the
number of iterations, cut to 1/8 of the printed (or, for the GA, our) count, and of seeds, 15
(the rank-sum test below gives p = 0.002 on them, 2e-5 on 30), so that 75 runs take some 9 s
of CPU: the wolf packs 6 of 50, ACA and AFSA 12 of 100, the GA 12 of 100.
The full budget runs in ``benchmarks/bench_papers.py`` (seeds 100..129), which also prints
the 95 % interval of the improvement next to the paper's 3.9 %.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import ranksums

from planning.paths import plan_path
from planning.paths.compare import toy_scene

pytestmark = pytest.mark.paper

START, GOAL = [1.0, 1.0, 1.0], [100.0, 100.0, 100.0]
SEEDS = range(15)
#: Iterations at 1/8 of the full run (see the module docstring).
BUDGET = {
    "wolfpack_improved": {"iterations": 6},
    "wolfpack": {"iterations": 6},
    "aca": {"iterations": 12},
    "ga": {"iterations": 12},
    "afsa": {"iterations": 12},
}
#: Table 3 (best, mean) as printed.
PAPER = {"wolfpack_improved": (66.731, 66.863), "wolfpack": (68.315, 69.561),
         "aca": (104.516, 106.256), "ga": (75.261, 76.163), "afsa": (86.631, 89.901)}



@pytest.fixture(scope="module")
def table3():
    """Per algorithm: the optimiser's own path length (what the paper reports, before our
    shortcutting) of each seed's run, and whether the run found a clear path."""
    scene = toy_scene()
    out = {}
    for algorithm, params in BUDGET.items():
        runs = [plan_path(scene, START, GOAL, algorithm, seed, params) for seed in SEEDS]
        out[algorithm] = (np.array([r.raw_length for r in runs]),
                          np.array([r.success for r in runs]))
    return out


def test_the_wolf_packs_find_clear_paths(table3):
    for algorithm in ("wolfpack_improved", "wolfpack"):
        assert table3[algorithm][1].all(), algorithm


def test_improved_wolf_pack_is_shorter_than_the_basic_one(table3, capsys):
    """Table 3: best 66.731 vs 68.315 and mean 66.863 vs 69.561 (3.9 % shorter)."""
    imp, bas = table3["wolfpack_improved"][0], table3["wolfpack"][0]
    shorter = 100 * (1 - imp.mean() / bas.mean())
    with capsys.disabled():
        print(f"\npaper 000 Table 3, toy scene, 15 seeds at 1/8 budget: mean path improved "
              f"{imp.mean():.2f} vs basic {bas.mean():.2f} mm ({shorter:.1f} % shorter; paper "
              f"3.9 %), best {imp.min():.2f} vs {bas.min():.2f} mm")
    assert imp.mean() < bas.mean()
    assert imp.min() < bas.min()
    assert ranksums(imp, bas, alternative="less").pvalue < 0.05  # not a fluke of the mean


def test_improved_wolf_pack_has_the_shortest_mean_path_of_the_five(table3, capsys):
    means = {a: v[0].mean() for a, v in table3.items()}
    order = sorted(means, key=means.get)
    with capsys.disabled():
        print("ours:  " + " < ".join(f"{a} {means[a]:.1f}" for a in order))
        print("paper: " + " < ".join(f"{a} {PAPER[a][1]:.1f}"
                                     for a in sorted(PAPER, key=lambda a: PAPER[a][1])))
    assert order[0] == "wolfpack_improved"
    # Where we differ from the paper: with the printed parameters (population 5) our GA ends
    # last, where the paper has it third; its ACA is last, ours third.
    assert order[-1] == "ga"
