//! The report as Markdown tables, and its matrices as CSV.

use std::fmt::Write as _;

use crate::Report;

fn pct(v: Option<f64>) -> String {
    v.map(|x| format!("{:.1}", x * 100.0))
        .unwrap_or_else(|| "-".into())
}

fn p(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.3e}")).unwrap_or_else(|| "-".into())
}

fn table(out: &mut String, head: &[String], rows: &[Vec<String>]) {
    let _ = writeln!(out, "| {} |", head.join(" | "));
    let _ = writeln!(out, "|{}", " --- |".repeat(head.len()));
    for r in rows {
        let _ = writeln!(out, "| {} |", r.join(" | "));
    }
    out.push('\n');
}

/// The confusion counts as CSV: `stimulus,<scenario>...`, one row per stimulus
/// scenario (the form the reference matrix is read in).
pub fn confusion_csv(r: &Report) -> String {
    let mut out = format!("stimulus,{}\n", r.scenarios.join(","));
    for (name, row) in r.scenarios.iter().zip(&r.confusion) {
        let cells: Vec<String> = row.iter().map(u64::to_string).collect();
        let _ = writeln!(out, "{name},{}", cells.join(","));
    }
    out
}

/// The report in Markdown.
pub fn render(r: &Report) -> String {
    let mut out = String::from("# Scenario classification report\n\n");
    let _ = writeln!(
        out,
        "{} participants, {} classification trials, {} scenarios (chance {:.1} %).\n",
        r.participants,
        r.trials,
        r.scenarios.len(),
        r.chance * 100.0
    );
    if let Some(a) = &r.accuracy {
        let _ = writeln!(
            out,
            "Top-choice accuracy: **{:.1} %** ({} of {}), 95 % Wilson interval {:.1} to {:.1} %.\n",
            a.value * 100.0,
            a.correct,
            a.trials,
            a.ci95_low * 100.0,
            a.ci95_high * 100.0
        );
    }
    if let Some(f) = &r.first_round {
        let _ = writeln!(
            out,
            "First round alone (round {}): {:.1} %.\n",
            f.round,
            f.accuracy.value * 100.0
        );
    }
    if r.top_ties > 0 {
        let _ = writeln!(
            out,
            "{} trials had a tie for the largest probability (counted for the first scenario).\n",
            r.top_ties
        );
    }
    confusion_table(&mut out, r);
    clustering_tables(&mut out, r);
    rating_tables(&mut out, r);
    out
}

/// The confusion matrix with recall, precision and binomial tests, and the Bhattacharyya
/// coefficients.
fn confusion_table(out: &mut String, r: &Report) {
    out.push_str("## Confusion (rows: stimulus; columns: top choice; % of the row)\n\n");
    let mut head = vec!["stimulus".to_string()];
    head.extend(r.scenarios.iter().cloned());
    head.extend(["n", "recall %", "precision %", "binomial p"].map(String::from));
    let rows: Vec<Vec<String>> = (0..r.scenarios.len())
        .map(|i| {
            let mut row = vec![r.scenarios[i].clone()];
            row.extend(
                (0..r.scenarios.len())
                    .map(|j| pct(r.confusion_normalised[i].as_ref().map(|v| v[j]))),
            );
            row.push(r.confusion[i].iter().sum::<u64>().to_string());
            row.extend([pct(r.recall[i]), pct(r.precision[i]), p(r.binomial_p[i])]);
            row
        })
        .collect();
    table(out, &head, &rows);
    if let Some(b) = &r.bhattacharyya {
        out.push_str("## Bhattacharyya coefficient against the reference, per row\n\n");
        let rows: Vec<Vec<String>> = r
            .scenarios
            .iter()
            .zip(b)
            .map(|(n, v)| {
                vec![
                    n.clone(),
                    v.map(|x| format!("{x:.3}")).unwrap_or("-".into()),
                ]
            })
            .collect();
        table(out, &["stimulus".into(), "coefficient".into()], &rows);
    }
}

/// The k-means criteria per k and the chosen clusters.
fn clustering_tables(out: &mut String, r: &Report) {
    if let Some(c) = &r.clustering {
        let _ = writeln!(out, "## k-means over the probability vectors\n\nCalinski-Harabasz chooses k = {}, the silhouette k = {}; the clusters below are for k = {}.\n", c.k_calinski_harabasz, c.k_silhouette, c.k);
        let rows: Vec<Vec<String>> = c
            .candidates
            .iter()
            .map(|k| {
                vec![
                    k.k.to_string(),
                    format!("{:.2}", k.calinski_harabasz),
                    format!("{:.3}", k.silhouette),
                    format!("{:.3}", k.inertia),
                ]
            })
            .collect();
        table(
            out,
            &["k", "Calinski-Harabasz", "silhouette", "inertia"].map(String::from),
            &rows,
        );
        if let Some(k) = c.candidates.iter().find(|k| k.k == c.k) {
            let mut head = vec!["cluster".to_string()];
            head.extend(r.scenarios.iter().map(|s| format!("mean p {s}")));
            head.extend(r.scenarios.iter().map(|s| format!("n {s}")));
            let rows: Vec<Vec<String>> = k
                .centers
                .iter()
                .zip(&c.membership)
                .enumerate()
                .map(|(i, (m, n))| {
                    let mut row = vec![(i + 1).to_string()];
                    row.extend(m.iter().map(|v| format!("{v:.2}")));
                    row.extend(n.iter().map(u64::to_string));
                    row
                })
                .collect();
            table(out, &head, &rows);
        }
    }
}

/// Valence and arousal: medians, Kruskal-Wallis, Dunn-Sidak.
fn rating_tables(out: &mut String, r: &Report) {
    for (name, rating) in [("Valence", &r.valence), ("Arousal", &r.arousal)] {
        if rating.count.iter().all(|c| *c == 0) {
            continue;
        }
        let _ = writeln!(out, "## {name}\n");
        if let Some(kw) = rating.kruskal_wallis {
            let _ = writeln!(
                out,
                "Kruskal-Wallis: H({}) = {:.2}, p = {:.3e}.\n",
                kw.df, kw.statistic, kw.p
            );
        }
        let mut head = vec!["stimulus".to_string(), "n".into(), "median".into()];
        head.extend(r.scenarios.iter().map(|s| format!("Dunn-Sidak p vs {s}")));
        let rows: Vec<Vec<String>> = (0..r.scenarios.len())
            .map(|i| {
                let mut row = vec![
                    r.scenarios[i].clone(),
                    rating.count[i].to_string(),
                    rating.median[i]
                        .map(|m| format!("{m}"))
                        .unwrap_or("-".into()),
                ];
                row.extend(rating.dunn_sidak[i].iter().map(|v| p(*v)));
                row
            })
            .collect();
        table(out, &head, &rows);
    }
}
