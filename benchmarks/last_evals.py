"""Final evaluation and the median of the last k evaluations of benchmark results (or runs' results.json).

A method whose evaluations swing (IQ-Learn) gives different numbers under the two protocols that papers
use: the last evaluation, and a summary of the last few. This prints both per file and their mean over files.

    python benchmarks/last_evals.py benchmarks/results/Hopper-v4/iqlearn-chi2-policy__*.json [--last 5]
"""

import argparse
import json

import numpy as np


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
        expert = results.get("expert_return") or float("nan")
        final, median = evals[-1]["mean"], float(np.median([e["mean"] for e in evals[-cli.last:]]))
        finals.append(final / expert)
        medians.append(median / expert)
        print(f"{path}: step {evals[-1]['step']}, final {final:.1f} ({final / expert:.2f} x expert), median of the last "
              f"{min(cli.last, len(evals))} {median:.1f} ({median / expert:.2f}); all: "
              + " / ".join(f"{e['mean']:.0f}" for e in evals))
    print(f"mean over {len(finals)} files: final {np.mean(finals):.3f} x expert, median of the last (up to) {cli.last} "
          f"{np.mean(medians):.3f} x expert")


if __name__ == "__main__":
    main()
