//! The tidy per-trial CSV: one row per trial, columns `participant`, `round`,
//! `position`, `stimulus`, then `p_<scenario>` per scenario (the normalised
//! probabilities, empty in a round without them), then `valence` and `arousal` (empty
//! outside the Self-Assessment Manikin round). R (`read.csv`) and pandas read it as is.
//! Also the reference matrix's CSV: `stimulus,<scenario>...`, one row per scenario.

use std::fmt::Write as _;

use crate::data::normalise;
use crate::{DataError, Reference, Responses, Trial};

/// Splits one CSV line: fields separated by commas, double-quoted fields may hold
/// commas and doubled quotes.
fn fields(line: &str) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    while let Some(c) = chars.next() {
        match (quoted, c) {
            (true, '"') if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            (true, '"') => quoted = false,
            (false, '"') if cur.is_empty() => quoted = true,
            (false, ',') => out.push(std::mem::take(&mut cur)),
            (_, c) => cur.push(c),
        }
    }
    if quoted {
        return Err("a quoted field is not closed".into());
    }
    out.push(cur);
    Ok(out)
}

fn quote(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The lines of a text with their 1-based numbers, blank lines skipped.
fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty())
}

fn bad(line: usize, problem: impl Into<String>) -> DataError {
    DataError::Line {
        line,
        problem: problem.into(),
    }
}

const LEAD: [&str; 4] = ["participant", "round", "position", "stimulus"];

/// The scenarios a header names, or what is wrong with it.
fn header(h: &[String]) -> Result<Vec<String>, String> {
    if h.len() < 8 || h[..4] != LEAD || h[h.len() - 2..] != ["valence", "arousal"] {
        return Err(format!(
            "the header must be {}, p_<scenario> for each of two or more scenarios, valence, arousal",
            LEAD.join(", ")
        ));
    }
    let mut scenarios = Vec::new();
    for c in &h[4..h.len() - 2] {
        let name = c
            .strip_prefix("p_")
            .filter(|n| !n.is_empty())
            .ok_or_else(|| format!("column {c:?} is not p_<scenario>"))?;
        if scenarios.iter().any(|s| s == name) {
            return Err(format!("scenario {name:?} has two columns"));
        }
        scenarios.push(name.to_string());
    }
    Ok(scenarios)
}

fn number(line: usize, column: &str, v: &str) -> Result<f64, DataError> {
    v.trim()
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
        .ok_or_else(|| bad(line, format!("{column}: {v:?} is not a number")))
}

fn count(line: usize, column: &str, v: &str) -> Result<u32, DataError> {
    v.trim()
        .parse::<u32>()
        .ok()
        .filter(|x| *x >= 1)
        .ok_or_else(|| bad(line, format!("{column}: {v:?} is not a whole number >= 1")))
}

fn optional(line: usize, column: &str, v: &str) -> Result<Option<f64>, DataError> {
    if v.trim().is_empty() {
        Ok(None)
    } else {
        number(line, column, v).map(Some)
    }
}

fn row(line: usize, f: &[String], scenarios: &[String]) -> Result<Trial, DataError> {
    let n = scenarios.len();
    if f.len() != n + 6 {
        return Err(bad(
            line,
            format!("{} fields where the header has {}", f.len(), n + 6),
        ));
    }
    let stimulus = scenarios.iter().position(|s| *s == f[3]).ok_or_else(|| {
        bad(
            line,
            format!("stimulus {:?} is none of the scenarios", f[3]),
        )
    })?;
    let raw = &f[4..4 + n];
    let probabilities = if raw.iter().all(|v| v.trim().is_empty()) {
        None
    } else {
        let vals = raw
            .iter()
            .zip(scenarios)
            .map(|(v, s)| number(line, &format!("p_{s}"), v))
            .collect::<Result<Vec<_>, _>>()?;
        Some(normalise(&vals).map_err(|p| bad(line, p))?)
    };
    Ok(Trial {
        participant: f[0].clone(),
        round: count(line, "round", &f[1])?,
        position: count(line, "position", &f[2])?,
        stimulus,
        probabilities,
        valence: optional(line, "valence", &f[n + 4])?,
        arousal: optional(line, "arousal", &f[n + 5])?,
    })
}

/// Reads a tidy CSV.
pub fn read(text: &str) -> Result<Responses, DataError> {
    let mut it = lines(text);
    let (hl, h) = it
        .next()
        .ok_or_else(|| DataError::Shape("the file is empty".into()))?;
    let scenarios = header(&fields(h).map_err(|p| bad(hl, p))?).map_err(|p| bad(hl, p))?;
    let mut trials = Vec::new();
    for (line, l) in it {
        let f = fields(l).map_err(|p| bad(line, p))?;
        trials.push(row(line, &f, &scenarios)?);
    }
    Ok(Responses { scenarios, trials })
}

fn num(v: Option<f64>) -> String {
    v.map(|x| format!("{x}")).unwrap_or_default()
}

/// Writes a tidy CSV (probabilities to the last bit: Rust's shortest round-trip form).
pub fn write(r: &Responses) -> String {
    let mut out = LEAD.join(",");
    for s in &r.scenarios {
        out.push_str(&format!(",{}", quote(&format!("p_{s}"))));
    }
    out.push_str(",valence,arousal\n");
    for t in &r.trials {
        let _ = write!(
            out,
            "{},{},{},{}",
            quote(&t.participant),
            t.round,
            t.position,
            quote(&r.scenarios[t.stimulus])
        );
        for i in 0..r.scenarios.len() {
            out.push(',');
            out.push_str(&num(t.probabilities.as_ref().map(|p| p[i])));
        }
        let _ = writeln!(out, ",{},{}", num(t.valence), num(t.arousal));
    }
    out
}

/// Reads a reference matrix: header `stimulus,<scenario>...`, then one row per
/// scenario, its name first, values >= 0 in any unit.
pub fn read_reference(text: &str) -> Result<Reference, DataError> {
    let mut it = lines(text);
    let (hl, h) = it
        .next()
        .ok_or_else(|| DataError::Shape("the file is empty".into()))?;
    let h = fields(h).map_err(|p| bad(hl, p))?;
    if h.len() < 3 || h[0] != "stimulus" {
        return Err(bad(
            hl,
            "the header must be stimulus, then two or more scenario names",
        ));
    }
    let scenarios: Vec<String> = h[1..].to_vec();
    let mut names = Vec::new();
    let mut rows = Vec::new();
    for (line, l) in it {
        let f = fields(l).map_err(|p| bad(line, p))?;
        if f.len() != h.len() {
            return Err(bad(
                line,
                format!("{} fields where the header has {}", f.len(), h.len()),
            ));
        }
        let vals = f[1..]
            .iter()
            .zip(&scenarios)
            .map(|(v, s)| number(line, s, v))
            .collect::<Result<Vec<_>, _>>()?;
        if vals.iter().any(|v| *v < 0.0) {
            return Err(bad(line, "a value is negative"));
        }
        names.push(f[0].clone());
        rows.push(vals);
    }
    // Rows in the columns' order, so that row i and column i are the same scenario.
    let ordered = scenarios
        .iter()
        .map(|s| {
            names
                .iter()
                .position(|n| n == s)
                .map(|i| rows[i].clone())
                .ok_or_else(|| DataError::Shape(format!("no row for scenario {s:?}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Reference {
        scenarios,
        rows: ordered,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const CSV: &str = "participant,round,position,stimulus,p_a,p_b,valence,arousal\n\
        \"p,1\",1,1,a,0.75,0.25,,\n\
        \"p,1\",2,1,b,,,3,7\n";

    #[test]
    fn reads_and_writes_back_the_same_text() {
        let r = read(CSV).unwrap();
        assert_eq!(r.scenarios, ["a", "b"]);
        assert_eq!(r.trials[0].participant, "p,1");
        assert_eq!(r.trials[0].probabilities, Some(vec![0.75, 0.25]));
        assert_eq!(r.trials[1].valence, Some(3.0));
        assert_eq!(write(&r), CSV);
    }

    #[test]
    fn errors_name_the_line_and_the_column() {
        let e =
            read("participant,round,position,stimulus,p_a,p_b,valence,arousal\nx,1,1,a,0.5,zz,,\n")
                .unwrap_err()
                .to_string();
        assert_eq!(e, "line 2: p_b: \"zz\" is not a number");
        let e = read("participant,round\n").unwrap_err().to_string();
        assert!(e.starts_with("line 1: the header must be"), "{e}");
        let e = read(
            "participant,round,position,stimulus,p_a,p_b,valence,arousal\nx,1,1,c,0.5,0.5,,\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("stimulus \"c\""), "{e}");
    }

    #[test]
    fn a_reference_is_put_in_column_order() {
        let r = read_reference("stimulus,a,b\nb,1,3\na,2,2\n").unwrap();
        assert_eq!(r.rows, vec![vec![2.0, 2.0], vec![1.0, 3.0]]);
        assert!(read_reference("stimulus,a,b\na,1,1\n").is_err());
    }
}
