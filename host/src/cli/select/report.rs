//! What `touchc select` prints and writes: the top recordings per class, the confusion
//! matrix, `report.json`, `scores.csv`, `scores.json`, and the trade table.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde_json::json;
use touchc_select::{Dataset, Selection};

/// A CSV field, quoted when it holds a comma, a quote or a line break.
pub(super) fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// How a recording is named in tables and files: its path as listed.
fn name(data: &Dataset, i: usize) -> String {
    data.listing.items[i].path.display().to_string()
}

/// `report.json`, `scores.csv` and `scores.json` of `sel` in `dir`.
pub(super) fn files(
    dir: &Path,
    sel: &Selection,
    data: &Dataset,
    top: &[Vec<usize>],
    seconds: f64,
    seed: u64,
) -> anyhow::Result<Vec<(PathBuf, Vec<u8>)>> {
    let classes = &data.listing.classes;
    let labels = data.labels();
    let top_json: serde_json::Map<String, serde_json::Value> = classes
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let rows: Vec<_> = top[k]
                .iter()
                .map(|&i| json!({"path": name(data, i), "score": sel.scores[i][k], "class": classes[labels[i]]}))
                .collect();
            (c.clone(), rows.into())
        })
        .collect();
    let report = json!({
        "scorer": sel.kind.name(),
        "accuracy": sel.metrics.accuracy,
        "macro_f1": sel.metrics.macro_f1,
        "confusion": sel.metrics.confusion,
        "classes": classes,
        "grouped": sel.folds.grouped,
        "folds": sel.folds.k,
        "seed": seed,
        "recordings": labels.len(),
        "seconds": seconds,
        "train_seconds": sel.train_s,
        "score_seconds": sel.score_s,
        "top": top_json,
    });
    let mut csv = Vec::new();
    writeln!(
        csv,
        "path,label,group,fold,predicted,{}",
        classes
            .iter()
            .map(|c| csv_field(c))
            .collect::<Vec<_>>()
            .join(",")
    )?;
    let mut rows = Vec::new();
    for (i, item) in data.listing.items.iter().enumerate() {
        let predicted = &classes[touchc_select::metrics::argmax(&sel.scores[i])];
        let cells: Vec<String> = sel.scores[i].iter().map(|v| format!("{v:.6}")).collect();
        writeln!(
            csv,
            "{},{},{},{},{},{}",
            csv_field(&name(data, i)),
            csv_field(&classes[item.label]),
            csv_field(item.group.as_deref().unwrap_or("")),
            sel.folds.fold[i],
            csv_field(predicted),
            cells.join(",")
        )?;
        rows.push(json!({
            "path": name(data, i),
            "label": classes[item.label],
            "group": item.group,
            "fold": sel.folds.fold[i],
            "predicted": predicted,
            "scores": sel.scores[i],
        }));
    }
    Ok(vec![
        (dir.join("report.json"), serde_json::to_vec_pretty(&report)?),
        (dir.join("scores.csv"), csv),
        (
            dir.join("scores.json"),
            serde_json::to_vec_pretty(&json!({"classes": classes, "recordings": rows}))?,
        ),
    ])
}

/// The top recordings of each class, the confusion matrix and the figures.
pub(super) fn tables(
    w: &mut impl Write,
    sel: &Selection,
    data: &Dataset,
    top: &[Vec<usize>],
) -> std::io::Result<()> {
    let classes = &data.listing.classes;
    let labels = data.labels();
    for (k, c) in classes.iter().enumerate() {
        writeln!(w, "{}:", super::super::report::escaped(c))?;
        for (rank, &i) in top[k].iter().enumerate() {
            let note = if labels[i] == k {
                String::new()
            } else {
                format!("  (labelled {})", classes[labels[i]])
            };
            writeln!(
                w,
                "  {:>2}. {:.3}  {}{}",
                rank + 1,
                sel.scores[i][k],
                super::super::report::escaped(&name(data, i)),
                super::super::report::escaped(&note)
            )?;
        }
    }
    let width = classes
        .iter()
        .map(|c| c.chars().count())
        .max()
        .unwrap_or(4)
        .clamp(4, 16);
    writeln!(w, "\nconfusion (rows: true class, columns: predicted)")?;
    write!(w, "{:width$}", "")?;
    for c in classes {
        write!(
            w,
            " {:>width$}",
            super::super::report::escaped(&c.chars().take(width).collect::<String>())
        )?;
    }
    writeln!(w)?;
    for (k, c) in classes.iter().enumerate() {
        write!(
            w,
            "{:width$}",
            super::super::report::escaped(&c.chars().take(width).collect::<String>())
        )?;
        for n in &sel.metrics.confusion[k] {
            write!(w, " {n:>width$}")?;
        }
        writeln!(w)?;
    }
    writeln!(
        w,
        "\n{} scorer, {} folds{}: accuracy {:.3}, macro-F1 {:.3} ({} recordings, {} classes)",
        sel.kind.name(),
        sel.folds.k,
        if sel.folds.grouped {
            " keeping each group whole"
        } else {
            " (stratified)"
        },
        sel.metrics.accuracy,
        sel.metrics.macro_f1,
        labels.len(),
        classes.len()
    )
}

/// `--trade`: both scorers' figures on the same folds (and `DIR/trade.json`).
pub(super) fn trade(
    runs: &[(Selection, f64)],
    data: &Dataset,
    dir: Option<&Path>,
) -> anyhow::Result<()> {
    let mut text = Vec::new();
    let first = &runs[0].0;
    writeln!(
        text,
        "{} recordings, {} classes, {} folds{}",
        data.samples.len(),
        data.listing.classes.len(),
        first.folds.k,
        if first.folds.grouped {
            " keeping each group whole"
        } else {
            " (stratified)"
        }
    )?;
    writeln!(
        text,
        "{:<10} {:>8} {:>8} {:>10} {:>10} {:>10}",
        "scorer", "accuracy", "macro-F1", "train s", "score s", "total s"
    )?;
    let mut rows = Vec::new();
    for (sel, seconds) in runs {
        writeln!(
            text,
            "{:<10} {:>8.3} {:>8.3} {:>10.2} {:>10.2} {:>10.2}",
            sel.kind.name(),
            sel.metrics.accuracy,
            sel.metrics.macro_f1,
            sel.train_s,
            sel.score_s,
            seconds
        )?;
        rows.push(json!({
            "scorer": sel.kind.name(),
            "accuracy": sel.metrics.accuracy,
            "macro_f1": sel.metrics.macro_f1,
            "train_seconds": sel.train_s,
            "score_seconds": sel.score_s,
            "seconds": seconds,
        }));
    }
    if let Some(dir) = dir {
        let json = serde_json::to_vec_pretty(
            &json!({"grouped": first.folds.grouped, "folds": first.folds.k, "scorers": rows}),
        )?;
        std::fs::create_dir_all(dir)
            .map_err(anyhow::Error::from)
            .and_then(|_| {
                Ok(crate::cli::output::write_atomic(
                    &dir.join("trade.json"),
                    &json,
                )?)
            })?;
    }
    crate::cli::output::write_atomic(Path::new("-"), &text)?;
    Ok(())
}
