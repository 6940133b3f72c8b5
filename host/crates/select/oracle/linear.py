"""The features scorer against a plain linear model fitted by scikit-learn.

Usage: python linear.py OUT_DIR DATA_DIR RATE_HZ

OUT_DIR is what `touchc select DATA_DIR/manifest.csv --model features -o OUT_DIR`
wrote: its `scores.csv` names every recording (paths relative to DATA_DIR) with its
class and the fold that held it out. Here about a hundred simple features of each recording
are computed with numpy, independently of touchc's own, and a multinomial logistic
regression (scikit-learn, standardised features, C = 1) is fitted on the same folds.
Prints both scorers' accuracy and macro-F1 and exits 1 when touchc's features
scorer is more than 3 points below the linear model. Python runs in this check only,
never in touchc.
"""

import csv
import json
import sys
from pathlib import Path

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.metrics import accuracy_score, f1_score
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

BANDS_HZ = [0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 20.0]


def stats(x):
    """Nine summary statistics of a series."""
    if x.size == 0:
        return [0.0] * 9
    q = np.percentile(x, [25, 50, 75, 90])
    sd = x.std()
    z = (x - x.mean()) / sd if sd > 0 else np.zeros_like(x)
    return [x.mean(), sd, x.max(), *q, (z**3).mean(), (z**4).mean()]


def bands(x, rate):
    """Share of the series' power (mean removed) in each band, and the peak's frequency."""
    x = x - x.mean()
    power = np.abs(np.fft.rfft(x)) ** 2
    freq = np.fft.rfftfreq(x.size, 1.0 / rate)
    total = power[1:].sum() or 1.0
    shares = [power[(freq >= lo) & (freq < hi)].sum() / total for lo, hi in zip(BANDS_HZ, BANDS_HZ[1:])]
    return shares + [freq[1:][power[1:].argmax()] if x.size > 2 else 0.0]


def features(frames, rate):
    x = np.nan_to_num(frames.astype(np.float64))
    x = np.clip(x - np.percentile(x, 10, axis=0), 0.0, None)
    t, rows, cols = x.shape
    p = x.reshape(t, -1).sum(axis=1)
    peak = x.reshape(t, -1).max(axis=1)
    level = 0.1 * max(peak.max(), 1e-9)
    area = (x > level).reshape(t, -1).sum(axis=1).astype(np.float64)
    touched = p > 0.1 * max(p.max(), 1e-9)
    starts = np.flatnonzero(np.diff(touched.astype(int)) == 1)
    bouts = len(starts) + int(touched[0])
    w = np.where(p > 0, p, 1.0)
    r = (x.sum(axis=2) * np.arange(rows)).sum(axis=1) / w
    c = (x.sum(axis=1) * np.arange(cols)).sum(axis=1) / w
    r, c = r[touched], c[touched]
    vr, vc = np.abs(np.diff(r)) * rate, np.abs(np.diff(c)) * rate
    speed = np.hypot(vr, vc)
    change = np.abs(np.diff(x, axis=0)).reshape(t - 1, -1).sum(axis=1)
    ac = []
    centred = p - p.mean()
    denom = (centred**2).sum() or 1.0
    for lag_s in [0.1, 0.2, 0.3, 0.5, 0.75, 1.0]:
        k = max(1, int(round(lag_s * rate)))
        ac.append((centred[:-k] * centred[k:]).sum() / denom if k < t else 0.0)
    crossings = np.count_nonzero(np.diff(np.sign(centred)) != 0)
    peaks = np.count_nonzero((p[1:-1] > p[:-2]) & (p[1:-1] >= p[2:]) & (p[1:-1] > level))
    mean_map = x.mean(axis=0)
    row_profile, col_profile = mean_map.sum(axis=1), mean_map.sum(axis=0)

    def spread(prof):
        at = np.arange(prof.size)
        mass = max(prof.sum(), 1e-9)
        centre = (prof * at).sum() / mass
        return np.sqrt(((at - centre) ** 2 * prof).sum() / mass)

    def range_of(v):
        return [v.mean(), v.std(), np.ptp(v)] if v.size else [0.0, 0.0, 0.0]

    return np.array(
        stats(p) + stats(area) + stats(peak)
        + [touched.mean(), bouts, touched.sum() / rate / max(bouts, 1)]
        + range_of(r) + range_of(c) + stats(speed) + stats(vc)[:6]
        + stats(change)[:6] + bands(p, rate)
        + (bands(c, rate) if c.size > 2 else [0.0] * 9)
        + (bands(r, rate) if r.size > 2 else [0.0] * 9)
        + ac + [crossings / t * rate, peaks / t * rate, spread(row_profile), spread(col_profile), t / rate],
        dtype=np.float64,
    )


def main():
    out, data, rate = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
    with open(out / "scores.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    report = json.loads((out / "report.json").read_text())
    classes = report["classes"]
    x = np.array([features(np.load(data / row["path"]), rate) for row in rows])
    y = np.array([classes.index(row["label"]) for row in rows])
    fold = np.array([int(row["fold"]) for row in rows])
    predicted = np.zeros_like(y)
    for k in np.unique(fold):
        model = make_pipeline(StandardScaler(), LogisticRegression(C=1.0, max_iter=5000))
        model.fit(x[fold != k], y[fold != k])
        predicted[fold == k] = model.predict(x[fold == k])
    linear = accuracy_score(y, predicted)
    ours = report["accuracy"]
    print(f"{len(rows)} recordings, {x.shape[1]} features, {len(np.unique(fold))} folds (grouped: {report['grouped']})")
    print("| scorer | accuracy | macro-F1 |")
    print("|---|---|---|")
    print(f"| touchc features | {ours:.3f} | {report['macro_f1']:.3f} |")
    print(f"| scikit-learn linear, {x.shape[1]} features | {linear:.3f} | {f1_score(y, predicted, average='macro'):.3f} |")
    if ours < linear - 0.03:
        print(f"FAIL: touchc's features scorer is {100 * (linear - ours):.1f} points below the linear model")
        sys.exit(1)


if __name__ == "__main__":
    main()
