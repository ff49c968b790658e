"""Final evaluation and the median of the last k evaluations of benchmark results (or runs' results.json).

A method whose evaluations swing (IQ-Learn) gives different numbers under the two protocols that papers
use: the last evaluation, and a summary of the last few. This prints both per file and their mean over files.

    python benchmarks/last_evals.py benchmarks/results/Hopper-v4/iqlearn-chi2-policy__*.json [--last 5]
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from sweep import normalized_score, random_return_of  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+",
                        help="results files (benchmarks/results/<env>/<algo>__<seed>.json or runs/<run>/results.json)")
    parser.add_argument("--last", type=int, default=5, help="how many of the last evaluations the median takes")
    cli = parser.parse_args()
    finals, medians = [], []
    for path in cli.files:
        with open(path) as f:
            results = json.load(f)
        evals = results["evals"]
        score = lambda ret: normalized_score(ret, random_return_of(results), results.get("expert_return"))
        score = score if score(0.0) is not None else lambda ret: float("nan")  # no expert or random return known
        final, median = evals[-1]["mean"], float(np.median([e["mean"] for e in evals[-cli.last:]]))
        finals.append(score(final))
        medians.append(score(median))
        print(f"{path}: step {evals[-1]['step']}, final {final:.1f} ({score(final):.2f} normalized), median of the "
              f"last {min(cli.last, len(evals))} {median:.1f} ({score(median):.2f}); all: "
              + " / ".join(f"{e['mean']:.0f}" for e in evals))
    print(f"mean over {len(finals)} files, normalized (random 0, expert 1): final {np.mean(finals):.3f}, median of the "
          f"last (up to) {cli.last} {np.mean(medians):.3f}")

if __name__ == "__main__":
    main()
