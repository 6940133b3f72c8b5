//! The report's figures as standalone SVG documents (no fonts to bundle: the viewer
//! draws the text).

use std::fmt::Write as _;

use crate::{Report, Responses};

/// A figure's file name (`confusion.svg`) and its SVG text.
pub type Figure = (&'static str, String);

const PALETTE: [&str; 8] = [
    "#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#9c755f",
];

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

fn open(w: f64, h: f64, title: &str) -> String {
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" \
         font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{}\" y=\"20\" text-anchor=\"middle\" font-size=\"15\">{}</text>\n",
        w / 2.0,
        esc(title)
    )
}

fn text(out: &mut String, x: f64, y: f64, anchor: &str, s: &str) {
    let _ = writeln!(
        out,
        "<text x=\"{x:.1}\" y=\"{y:.1}\" text-anchor=\"{anchor}\">{}</text>",
        esc(s)
    );
}

/// The row-normalised confusion matrix as a heat map, percentages in the cells.
fn confusion(r: &Report) -> String {
    let n = r.scenarios.len();
    let cell = 64.0;
    let (left, top) = (110.0, 60.0);
    let (w, h) = (left + cell * n as f64 + 20.0, top + cell * n as f64 + 50.0);
    let acc = r.accuracy.as_ref().map(|a| a.value * 100.0).unwrap_or(0.0);
    let mut s = open(
        w,
        h,
        &format!("Top choice, rows normalised (accuracy {acc:.1} %)"),
    );
    for (i, row) in r.confusion_normalised.iter().enumerate() {
        let y = top + cell * i as f64;
        text(
            &mut s,
            left - 6.0,
            y + cell / 2.0 + 4.0,
            "end",
            &r.scenarios[i],
        );
        for j in 0..n {
            let v = row.as_ref().map(|r| r[j]).unwrap_or(0.0);
            let x = left + cell * j as f64;
            let shade = (255.0 * (1.0 - v)).round() as u8;
            let _ = writeln!(
                s,
                "<rect x=\"{x}\" y=\"{y}\" width=\"{cell}\" height=\"{cell}\" fill=\"rgb({shade},{shade},255)\" stroke=\"#888\"/>"
            );
            let fill = if v > 0.5 { "white" } else { "black" };
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" fill=\"{fill}\">{:.0}</text>",
                x + cell / 2.0,
                y + cell / 2.0 + 4.0,
                v * 100.0
            );
        }
    }
    for (j, name) in r.scenarios.iter().enumerate() {
        text(
            &mut s,
            left + cell * (j as f64 + 0.5),
            top + cell * n as f64 + 16.0,
            "middle",
            name,
        );
    }
    text(
        &mut s,
        left + cell * n as f64 / 2.0,
        h - 10.0,
        "middle",
        "chosen scenario (rows: the stimulus's scenario)",
    );
    s + "</svg>\n"
}

/// A plot frame: axes from 0 to 1 on both sides, ticks every 0.2.
fn frame(s: &mut String, x0: f64, y0: f64, w: f64, h: f64, xlabel: &str, ylabel: &str) {
    let _ = writeln!(
        s,
        "<rect x=\"{x0}\" y=\"{y0}\" width=\"{w}\" height=\"{h}\" fill=\"none\" stroke=\"black\"/>"
    );
    for i in 0..=5 {
        let f = i as f64 / 5.0;
        text(s, x0 + w * f, y0 + h + 15.0, "middle", &format!("{f:.1}"));
        text(
            s,
            x0 - 5.0,
            y0 + h * (1.0 - f) + 4.0,
            "end",
            &format!("{f:.1}"),
        );
    }
    text(s, x0 + w / 2.0, y0 + h + 32.0, "middle", xlabel);
    let _ = writeln!(
        s,
        "<text transform=\"translate({:.1},{:.1}) rotate(-90)\" text-anchor=\"middle\">{}</text>",
        x0 - 38.0,
        y0 + h / 2.0,
        esc(ylabel)
    );
}

/// Accuracy against the probability cut-off, top-1/2/3 sums.
fn cutoff(r: &Report) -> Option<String> {
    let c = r.cutoffs.as_ref()?;
    let (x0, y0, w, h) = (60.0, 40.0, 420.0, 260.0);
    let mut s = open(
        560.0,
        350.0,
        "Top-choice accuracy against a probability cut-off",
    );
    frame(
        &mut s,
        x0,
        y0,
        w,
        h,
        "cut-off on the summed probability",
        "accuracy",
    );
    for (k, (name, ys)) in [("top-1", &c.top1), ("top-2", &c.top2), ("top-3", &c.top3)]
        .iter()
        .enumerate()
    {
        let pts: Vec<String> = c
            .cutoff
            .iter()
            .zip(ys.iter())
            .map(|(x, y)| format!("{:.1},{:.1}", x0 + w * x, y0 + h * (1.0 - y)))
            .collect();
        let _ = writeln!(
            s,
            "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"2\" points=\"{}\"/>",
            PALETTE[k],
            pts.join(" ")
        );
        let _ = writeln!(
            s,
            "<rect x=\"{}\" y=\"{}\" width=\"12\" height=\"4\" fill=\"{}\"/>",
            x0 + w + 10.0,
            y0 + 10.0 + 18.0 * k as f64,
            PALETTE[k]
        );
        text(
            &mut s,
            x0 + w + 26.0,
            y0 + 15.0 + 18.0 * k as f64,
            "start",
            name,
        );
    }
    Some(s + "</svg>\n")
}

/// Per cluster: its mean probabilities (colour) and its share of each stimulus (grey).
fn clusters(r: &Report) -> Option<String> {
    let cl = r.clustering.as_ref()?;
    let cand = cl.candidates.iter().find(|c| c.k == cl.k)?;
    let n = r.scenarios.len();
    let (pw, ph) = (36.0 * n as f64, 120.0);
    let w = 90.0 + pw * 2.0 + 40.0;
    let h = 60.0 + (ph + 40.0) * cl.k as f64 + 40.0;
    let mut s = open(
        w,
        h,
        &format!("k-means, {} clusters (Calinski-Harabasz)", cl.k),
    );
    text(&mut s, 90.0 + pw / 2.0, 45.0, "middle", "cluster mean");
    text(
        &mut s,
        110.0 + pw * 1.5,
        45.0,
        "middle",
        "share of each stimulus",
    );
    for (c, center) in cand.centers.iter().enumerate() {
        let y = 60.0 + (ph + 40.0) * c as f64;
        let size: u64 = cl.membership[c].iter().sum();
        text(
            &mut s,
            80.0,
            y + ph / 2.0,
            "end",
            &format!("{} (n={size})", c + 1),
        );
        let totals: Vec<u64> = (0..n)
            .map(|j| cl.membership.iter().map(|m| m[j]).sum())
            .collect();
        for j in 0..n {
            let share = if totals[j] > 0 {
                cl.membership[c][j] as f64 / totals[j] as f64
            } else {
                0.0
            };
            for (x, v, fill) in [
                (90.0, center[j], PALETTE[j % 8]),
                (110.0 + pw, share, "#555"),
            ] {
                let bx = x + 36.0 * j as f64 + 4.0;
                let _ = writeln!(s, "<rect x=\"{bx:.1}\" y=\"{:.1}\" width=\"28\" height=\"{:.1}\" fill=\"{fill}\"/>", y + ph * (1.0 - v), ph * v);
            }
            let _ = writeln!(
                s,
                "<line x1=\"90\" x2=\"{0}\" y1=\"{1}\" y2=\"{1}\" stroke=\"black\"/>",
                110.0 + pw * 2.0,
                y + ph
            );
            for x in [90.0, 110.0 + pw] {
                let _ = writeln!(s, "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"9\" text-anchor=\"middle\">{}</text>", x + 36.0 * j as f64 + 18.0, y + ph + 12.0, esc(&r.scenarios[j]));
            }
        }
    }
    Some(s + "</svg>\n")
}

/// Median, quartiles and range per stimulus scenario, for valence and arousal.
fn sam(r: &Report, ratings: &[(&str, Vec<Vec<f64>>)]) -> Option<String> {
    if ratings.iter().all(|(_, g)| g.iter().all(Vec::is_empty)) {
        return None;
    }
    let n = r.scenarios.len();
    let pw = 64.0 * n as f64;
    let mut s = open(
        60.0 + (pw + 60.0) * 2.0,
        330.0,
        "Self-Assessment Manikin per stimulus (1-9)",
    );
    for (k, (name, groups)) in ratings.iter().enumerate() {
        let x0 = 50.0 + (pw + 60.0) * k as f64;
        let (y0, h) = (50.0, 220.0);
        let y = |v: f64| y0 + h * (9.0 - v) / 8.0;
        let _ = writeln!(s, "<rect x=\"{x0}\" y=\"{y0}\" width=\"{pw}\" height=\"{h}\" fill=\"none\" stroke=\"black\"/>");
        text(&mut s, x0 + pw / 2.0, y0 - 8.0, "middle", name);
        for v in 1..=9 {
            text(&mut s, x0 - 5.0, y(v as f64) + 4.0, "end", &v.to_string());
        }
        for (j, g) in groups.iter().enumerate() {
            let cx = x0 + 64.0 * j as f64 + 32.0;
            text(&mut s, cx, y0 + h + 15.0, "middle", &r.scenarios[j]);
            if g.is_empty() {
                continue;
            }
            let mut v = g.clone();
            v.sort_by(f64::total_cmp);
            let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
            let _ = writeln!(
                s,
                "<line x1=\"{cx}\" x2=\"{cx}\" y1=\"{:.1}\" y2=\"{:.1}\" stroke=\"black\"/>",
                y(v[0]),
                y(v[v.len() - 1])
            );
            let _ = writeln!(s, "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"30\" height=\"{:.1}\" fill=\"{}\" stroke=\"black\"/>", cx - 15.0, y(q(0.75)), (y(q(0.25)) - y(q(0.75))).max(1.0), PALETTE[j % 8]);
            let _ = writeln!(s, "<line x1=\"{:.1}\" x2=\"{:.1}\" y1=\"{2:.1}\" y2=\"{2:.1}\" stroke=\"black\" stroke-width=\"3\"/>", cx - 15.0, cx + 15.0, y(q(0.5)));
        }
    }
    Some(s + "</svg>\n")
}

/// Every figure the report of `responses` has data for.
pub fn all(r: &Report, responses: &Responses) -> Vec<Figure> {
    let valence = responses.ratings(|t| t.valence);
    let arousal = responses.ratings(|t| t.arousal);
    let mut out = vec![("confusion.svg", confusion(r))];
    out.extend(cutoff(r).map(|f| ("cutoff.svg", f)));
    out.extend(clusters(r).map(|f| ("clusters.svg", f)));
    out.extend(sam(r, &[("valence", valence), ("arousal", arousal)]).map(|f| ("sam.svg", f)));
    out
}
