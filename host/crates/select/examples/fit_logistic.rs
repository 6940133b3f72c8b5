//! The features scorer's regression on a table, for `oracle/logistic.py` (scikit-learn's
//! `LogisticRegression` as the independent oracle): reads `class,x1,x2,...` rows from
//! the CSV file given, fits [`Logistic`] with `CLASSES` classes, and prints each row's
//! class probabilities as CSV.
//!
//! `cargo run --release -p touchc-select --example fit_logistic -- rows.csv CLASSES`

use std::process::ExitCode;

use touchc_select::logistic::Logistic;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [path, classes] = args.as_slice() else {
        eprintln!("usage: fit_logistic ROWS.csv CLASSES");
        return ExitCode::from(2);
    };
    let Ok(classes) = classes.parse::<usize>() else {
        eprintln!("fit_logistic: CLASSES must be a whole number, not {classes:?}");
        return ExitCode::from(2);
    };
    let text = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) => {
            eprintln!("fit_logistic: {path}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for (n, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let fields: Result<Vec<f64>, _> = line.split(',').map(|f| f.trim().parse()).collect();
        match fields.as_deref() {
            Ok([label, row @ ..])
                if label.fract() == 0.0 && (0.0..classes as f64).contains(label) =>
            {
                y.push(*label as usize);
                x.push(row.to_vec());
            }
            _ => {
                eprintln!(
                    "fit_logistic: {path}:{}: not `class,x1,x2,...` with a class below {classes}",
                    n + 1
                );
                return ExitCode::FAILURE;
            }
        }
    }
    let model = Logistic::fit(&x, &y, classes);
    for row in &x {
        let p: Vec<String> = model
            .predict(row)
            .iter()
            .map(|v| format!("{v:.12e}"))
            .collect();
        println!("{}", p.join(","));
    }
    ExitCode::SUCCESS
}
