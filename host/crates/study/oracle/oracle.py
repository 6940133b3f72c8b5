"""Checks `touchc study report` against scipy and scikit-learn on generated response sets.

Usage: python oracle.py path/to/touchc [WORKDIR]
       python oracle.py --example OUT.csv   (a simulated study for the docs' figures)

Each set is written as a tidy CSV (and a reference matrix for some), the real `touchc`
binary reports it with -o, and every statistic in report.json is recomputed here with
numpy / scipy / scikit-learn and compared within 1e-9 relative (1e-15 absolute for
values that cancel to about zero). Python is used by this test only, never by touchc.
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import stats
from scipy.spatial.distance import cdist
from sklearn.cluster import KMeans
from sklearn.metrics import calinski_harabasz_score, silhouette_score

REL = 1e-9
ABS = 1e-15
checked = 0


def close(a, b, what):
    global checked
    checked += 1
    if a is None or b is None:
        assert a is None and b is None, f"{what}: {a} against {b}"
        return
    a, b = float(a), float(b)
    if np.isnan(b):
        raise AssertionError(f"{what}: oracle is nan, touchc gave {a}")
    assert abs(a - b) <= max(REL * max(abs(a), abs(b)), ABS), f"{what}: touchc {a!r} against {b!r}"


def close_all(a, b, what):
    assert (a is None) == (b is None), f"{what}: {a} against {b}"
    if a is None:
        return
    a, b = list(a), list(b)
    assert len(a) == len(b), f"{what}: lengths {len(a)} and {len(b)}"
    for i, (x, y) in enumerate(zip(a, b)):
        if isinstance(y, (list, tuple, np.ndarray)) or isinstance(x, list):
            close_all(x, y, f"{what}[{i}]")
        else:
            close(x, y, f"{what}[{i}]")


# ---------------------------------------------------------------- generation

def dirichlet_rows(rng, truth, s, strength, conc=1.0):
    a = np.full(s, conc)
    a[truth] += strength
    return rng.dirichlet(a)


def make_set(rng, s=6, people=30, rounds=3, sam=True, strength=3.0, grid=None, kind="normal"):
    names = [f"s{i}" for i in range(s)] if kind != "named" else ["attention", "calming", "gratitude", "happiness", "love", "sadness"][:s]
    rows = []
    for person in range(people):
        pid = f"p{person:02d}"
        for r in range(1, rounds + 1):
            for pos, stim in enumerate(rng.permutation(s), 1):
                if kind == "identical":
                    p = np.arange(1, s + 1, dtype=float)
                elif kind == "perfect":
                    p = np.full(s, 0.02)
                    p[stim] = 1.0
                else:
                    p = dirichlet_rows(rng, stim, s, strength)
                    if kind == "never":
                        p[s - 1] = 0.0
                    if grid:
                        p = np.round(p / grid) * grid
                        if p.sum() == 0:
                            p[stim] = grid
                    if kind == "ties" and rng.random() < 0.4:
                        p = np.zeros(s)
                        p[stim] = 0.5
                        p[(stim + 1) % s] = 0.5
                rows.append([pid, r, pos, names[stim], list(p), None, None])
        if sam:
            for pos, stim in enumerate(rng.permutation(s), 1):
                if kind == "identical":
                    v, a = 5, 5
                else:
                    v = int(np.clip(round(rng.normal(3 + stim, 1.5)), 1, 9))
                    a = int(np.clip(round(rng.normal(7 - stim * 0.5, 2)), 1, 9))
                rows.append([pid, rounds + 1, pos, names[stim], None, v, a])
    return names, rows


def write_csv(path, names, rows):
    with open(path, "w") as f:
        f.write("participant,round,position,stimulus," + ",".join("p_" + n for n in names) + ",valence,arousal\n")
        for pid, r, pos, stim, p, v, a in rows:
            ps = ",".join(repr(float(x)) for x in p) if p is not None else "," * (len(names) - 1)
            f.write(f"{pid},{r},{pos},{stim},{ps},{'' if v is None else v},{'' if a is None else a}\n")


# ---------------------------------------------------------------- oracles

def normalised(raw):
    total = 0.0
    for x in raw:
        total += x
    return [x / total for x in raw]


def wilson(k, n):
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="wilson")
    return ci.low, ci.high


def check_accuracy(rep, truth, top, what):
    n = len(truth)
    if n == 0:
        assert rep is None, what
        return
    k = int(np.sum(truth == top))
    assert rep["correct"] == k and rep["trials"] == n, what
    close(rep["value"], k / n, what + ".value")
    lo, hi = wilson(k, n)
    close(rep["ci95_low"], lo, what + ".ci95_low")
    close(rep["ci95_high"], hi, what + ".ci95_high")


def confusion(truth, top, s):
    m = np.zeros((s, s), dtype=int)
    for t, c in zip(truth, top):
        m[t, c] += 1
    return m


def dunn_sidak(groups):
    k = len(groups)
    out = [[None] * k for _ in range(k)]
    live = [i for i in range(k) if len(groups[i]) > 0]
    if len(live) < 2:
        return out
    allv = np.concatenate([np.asarray(g, float) for g in groups if len(g)])
    n = len(allv)
    ranks = stats.rankdata(allv)
    _, counts = np.unique(allv, return_counts=True)
    ties = float(np.sum(counts ** 3 - counts))
    var = n * (n + 1) / 12.0 - ties / (12.0 * (n - 1))
    if var <= 0:
        return out
    mean_rank, at = {}, 0
    for i in live:
        mean_rank[i] = ranks[at:at + len(groups[i])].mean()
        at += len(groups[i])
    m = len(live) * (len(live) - 1) / 2
    for a, i in enumerate(live):
        for j in live[a + 1:]:
            z = abs(mean_rank[i] - mean_rank[j]) / np.sqrt(var * (1 / len(groups[i]) + 1 / len(groups[j])))
            p = min(1.0, 2 * stats.norm.sf(z))
            with np.errstate(divide="ignore"):
                adj = -np.expm1(m * np.log1p(-p))
            out[i][j] = out[j][i] = adj
    return out


def check_rating(rep, groups, what):
    assert rep["count"] == [len(g) for g in groups], what
    close_all(rep["median"], [float(np.median(g)) if len(g) else None for g in groups], what + ".median")
    live = [g for g in groups if len(g)]
    allv = [x for g in live for x in g]
    if len(live) < 2 or len(set(allv)) == 1:
        assert rep["kruskal_wallis"] is None, what
    else:
        h, p = stats.kruskal(*live)
        kw = rep["kruskal_wallis"]
        close(kw["statistic"], h, what + ".H")
        close(kw["p"], p, what + ".p")
        assert kw["df"] == len(live) - 1
    close_all(rep["dunn_sidak"], dunn_sidak(groups), what + ".dunn_sidak")


def lloyd_ties(X, init):
    """Plain Lloyd from `init` with numpy's first-index argmin; also whether any point
    was ever exactly equidistant from its two nearest centers."""
    C, lab, tied = init.copy(), None, False
    for _ in range(300):
        d = ((X[:, None, :] - C[None]) ** 2).sum(-1)
        part = np.sort(d, axis=1)
        tied |= bool(np.any(part[:, 0] == part[:, 1]))
        new = d.argmin(1)
        if lab is not None and (new == lab).all():
            break
        lab = new
        C = np.array([X[lab == j].mean(0) for j in range(len(C))])
    inertia = float(((X - C[lab]) ** 2).sum())
    return lab, C, inertia, tied


tie_runs = 0


def check_clustering(rep, X, truth, s):
    global tie_runs
    n = len(X)
    distinct = len({tuple(x) for x in X}) if n else 0
    top = min(10, distinct, n - 1)
    if top < 2:
        assert rep is None, "clustering should be absent"
        return
    cands = rep["candidates"]
    assert [c["k"] for c in cands] == list(range(2, top + 1)), [c["k"] for c in cands]
    D = cdist(X, X)
    chs, sils = [], []
    for c in cands:
        k = c["k"]
        init = np.array(c["init"])
        # scikit-learn centres the data first, so a point exactly equidistant from two
        # centers goes wherever rounding sends it; such runs are checked against plain
        # Lloyd with numpy's first-index rule (touchc's), the criteria still by sklearn.
        labels, centers, inertia, tied = lloyd_ties(X, init)
        if tied:
            tie_runs += 1
        else:
            km = KMeans(n_clusters=k, init=init, n_init=1, algorithm="lloyd", tol=0.0, max_iter=300).fit(X)
            labels, centers, inertia = km.labels_, km.cluster_centers_, km.inertia_
        close(c["inertia"], inertia, f"k={k} inertia")
        close_all(c["centers"], centers, f"k={k} centers")
        ch = calinski_harabasz_score(X, labels)
        sil = silhouette_score(D, labels, metric="precomputed")
        close(c["calinski_harabasz"], ch, f"k={k} CH")
        close(c["silhouette"], sil, f"k={k} silhouette")
        chs.append(ch)
        sils.append(sil)
        if k == rep["k"]:
            assert list(labels) == rep["labels"], "labels"
            member = np.zeros((k, s), dtype=int)
            for l, t in zip(labels, truth):
                member[l, t] += 1
            assert member.tolist() == rep["membership"], "membership"
    assert rep["k_calinski_harabasz"] == cands[int(np.argmax(chs))]["k"]
    assert rep["k_silhouette"] == cands[int(np.argmax(sils))]["k"]
    assert rep["k"] == rep["k_calinski_harabasz"]


def check(report, names, rows, reference):
    s = len(names)
    cls = [(r[1], names.index(r[3]), normalised(r[4])) for r in rows if r[4] is not None]
    truth = np.array([c[1] for c in cls], dtype=int)
    P = np.array([c[2] for c in cls]) if cls else np.zeros((0, s))
    top = np.argmax(P, axis=1) if cls else np.zeros(0, dtype=int)
    assert report["scenarios"] == names
    assert report["trials"] == len(cls)
    assert report["participants"] == len({r[0] for r in rows})
    m = confusion(truth, top, s)
    assert report["confusion"] == m.tolist(), "confusion"
    rows_n = [None if m[i].sum() == 0 else m[i] / m[i].sum() for i in range(s)]
    close_all(report["confusion_normalised"], rows_n, "confusion_normalised")
    close_all(report["recall"], [None if m[i].sum() == 0 else m[i, i] / m[i].sum() for i in range(s)], "recall")
    close_all(report["precision"], [None if m[:, j].sum() == 0 else m[j, j] / m[:, j].sum() for j in range(s)], "precision")
    check_accuracy(report["accuracy"], truth, top, "accuracy")
    binom = [None if m[i].sum() == 0 else stats.binomtest(int(m[i, i]), int(m[i].sum()), 1 / s).pvalue for i in range(s)]
    close_all(report["binomial_p"], binom, "binomial_p")
    if cls:
        first = min(c[0] for c in cls)
        sel = np.array([c[0] == first for c in cls])
        fr = report["first_round"]
        assert fr["round"] == first
        check_accuracy(fr["accuracy"], truth[sel], top[sel], "first_round")
        assert fr["confusion"] == confusion(truth[sel], top[sel], s).tolist()
        cut = report["cutoffs"]
        close_all(cut["cutoff"], [i / 20 for i in range(21)], "cutoff values")
        for n_top in (1, 2, 3):
            sums = np.cumsum(-np.sort(-P, axis=1), axis=1)[:, min(n_top, s) - 1]
            want = [float(np.mean((truth == top) & (sums >= c))) for c in cut["cutoff"]]
            close_all(cut[f"top{n_top}"], want, f"top{n_top}")
    else:
        assert report["first_round"] is None and report["cutoffs"] is None
    if reference is not None:
        want = []
        for i in range(s):
            p, q = m[i].astype(float), np.asarray(reference[i], float)
            want.append(None if p.sum() == 0 or q.sum() == 0 else float(np.sum(np.sqrt(p / p.sum() * (q / q.sum())))))
        close_all(report["bhattacharyya"], want, "bhattacharyya")
    else:
        assert report["bhattacharyya"] is None
    check_clustering(report["clustering"], P, truth, s)
    for scale, col in (("valence", 5), ("arousal", 6)):
        groups = [[float(r[col]) for r in rows if r[col] is not None and r[3] == name] for name in names]
        check_rating(report[scale], groups, scale)
        assert report["kruskal_wallis"][scale] == report[scale]["kruskal_wallis"]


def cases(rng):
    yield "paper-sized", make_set(rng)
    yield "named", make_set(rng, kind="named")
    yield "one participant", make_set(rng, people=1)
    yield "a scenario never chosen", make_set(rng, kind="never")
    yield "all responses identical", make_set(rng, people=5, kind="identical")
    yield "ties", make_set(rng, kind="ties", people=8)
    yield "slider steps of 0.05", make_set(rng, grid=0.05, people=12)
    yield "slider steps of 0.25", make_set(rng, grid=0.25, people=6)
    yield "perfect", make_set(rng, kind="perfect", people=4)
    yield "two scenarios", make_set(rng, s=2, people=10)
    yield "three scenarios, no manikin round", make_set(rng, s=3, sam=False)
    yield "chance level", make_set(rng, strength=0.0, people=20)
    yield "large", make_set(rng, people=120, rounds=4, strength=1.0)
    yield "one round", make_set(rng, rounds=1, people=15)
    yield "eight scenarios", make_set(rng, s=8, people=9)
    yield "manikin only", make_set(rng, rounds=0, people=10)
    for i in range(8):
        yield f"random {i}", make_set(rng, s=int(rng.integers(2, 9)), people=int(rng.integers(1, 25)),
                                      rounds=int(rng.integers(1, 5)), sam=bool(rng.random() < 0.7),
                                      strength=float(rng.uniform(0, 6)))


def main():
    if sys.argv[1] == "--example":
        # A simulated paper-sized study with the emoji's names, for the docs' figures.
        names, rows = make_set(np.random.default_rng(30), kind="named", strength=2.0)
        write_csv(sys.argv[2], names, rows)
        return
    touchc = sys.argv[1]
    work = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(tempfile.mkdtemp())
    rng = np.random.default_rng(37)
    n = 0
    for i, (name, (names, rows)) in enumerate(cases(rng)):
        d = work / f"set{i:02d}"
        d.mkdir(parents=True, exist_ok=True)
        csv = d / "trials.csv"
        write_csv(csv, names, rows)
        args = [touchc, "study", "report", str(csv), "-o", str(d / "out")]
        reference = None
        if i % 2 == 0:
            s = len(names)
            reference = rng.integers(0, 40, size=(s, s)).astype(float)
            if i % 4 == 0:
                reference[0] = 0.0
            with open(d / "reference.csv", "w") as f:
                f.write("stimulus," + ",".join(names) + "\n")
                for nm, row in zip(names, reference):
                    f.write(nm + "," + ",".join(str(int(v)) for v in row) + "\n")
            args += ["--reference", str(d / "reference.csv")]
        res = subprocess.run(args, capture_output=True, text=True)
        assert res.returncode == 0, f"{name}: touchc failed: {res.stderr}"
        report = json.loads((d / "out" / "report.json").read_text())
        try:
            check(report, names, rows, reference)
        except AssertionError as e:
            raise SystemExit(f"set {i} ({name}): {e}")
        n += 1
        print(f"ok  set {i:2d}: {name}")
    assert n >= 20
    print(f"all {n} response sets match scipy / scikit-learn ({checked} values compared; "
          f"{tie_runs} k-means runs with exact distance ties checked against plain Lloyd)")


if __name__ == "__main__":
    main()
