"""The features scorer's regression against scikit-learn's LogisticRegression.

Usage: python logistic.py FIT_LOGISTIC_BINARY WORKDIR

Fits tables of several shapes (six classes, two classes, a class the training set
lacks, a constant column, features of very different scales) with touchc's
`Logistic::fit` (smartcore's L-BFGS on standardised features, L2 = 1 on the summed
cross-entropy) and with scikit-learn (StandardScaler, then LogisticRegression with
C = 1, lbfgs, a tight tolerance), and compares every predicted probability. Exits 1
on the first table whose probabilities differ by more than 1e-4.
"""

import subprocess
import sys

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.preprocessing import StandardScaler

TOLERANCE = 1e-4


def table(rng, n, d, classes, present, spread, scales):
    """n rows of d features in `present` classes (of `classes`), class means `spread` apart."""
    means = rng.normal(0.0, spread, size=(classes, d))
    y = rng.choice(present, size=n)
    x = means[y] + rng.normal(0.0, 1.0, size=(n, d))
    return x * scales, y


def check(binary, workdir, name, x, y, classes):
    path = f"{workdir}/{name}.csv"
    np.savetxt(path, np.column_stack([y, x]), delimiter=",", fmt="%.17g")
    out = subprocess.run([binary, path, str(classes)], check=True, capture_output=True, text=True)
    ours = np.loadtxt(out.stdout.splitlines(), delimiter=",", ndmin=2)
    z = StandardScaler().fit_transform(x)
    model = LogisticRegression(C=1.0, tol=1e-12, max_iter=100_000).fit(z, y)
    theirs = np.zeros((len(y), classes))
    theirs[:, model.classes_] = model.predict_proba(z)
    diff = np.abs(ours - theirs).max()
    absent = [c for c in range(classes) if c not in model.classes_]
    print(f"{name}: {len(y)} rows, {x.shape[1]} features, classes {[int(c) for c in model.classes_]} of {classes}"
          f" (absent {absent}): largest difference {diff:.2e}")
    if not diff <= TOLERANCE:
        print(f"{name}: touchc's probabilities differ from scikit-learn's by {diff:.2e} > {TOLERANCE}")
        sys.exit(1)


def main():
    binary, workdir = sys.argv[1], sys.argv[2]
    rng = np.random.default_rng(7)
    ones = lambda d: np.ones(d)
    cases = [
        ("six_classes", 560, 72, 6, list(range(6)), 0.4, ones(72)),
        ("two_classes", 200, 10, 2, [0, 1], 0.5, ones(10)),
        ("one_class_absent", 300, 12, 5, [0, 1, 3, 4], 0.6, ones(12)),
        ("two_of_four", 150, 6, 4, [1, 3], 0.7, ones(6)),
        ("scales", 400, 20, 3, [0, 1, 2], 0.5, 10.0 ** rng.uniform(-4, 4, size=20)),
        ("separable", 90, 3, 3, [0, 1, 2], 6.0, ones(3)),
    ]
    for name, n, d, classes, present, spread, scales in cases:
        x, y = table(rng, n, d, classes, present, spread, scales)
        check(binary, workdir, name, x, y, classes)
    x, y = table(rng, 120, 8, 3, [0, 1, 2], 0.5, ones(8))
    x[:, 4] = 2.5  # a constant feature: scaled by 1, it carries no weight in either fit
    check(binary, workdir, "constant_column", x, y, 3)
    print("logistic oracle: every table within", TOLERANCE)


if __name__ == "__main__":
    main()
