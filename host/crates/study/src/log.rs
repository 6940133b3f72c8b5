//! The session log: JSON lines, one record per line, appended and flushed as the
//! session goes. A `session` record opens each run of a session (a resumed one adds
//! another), a `trial` record holds one answered trial with the device's ticks, and
//! `event` records note what else happened (a refusal, a pause). A crash can leave at
//! most one unfinished last line; [`read`] skips it.

use serde::{Deserialize, Serialize};

use crate::{DataError, Responses, Trial};

/// The log format's version, in every `session` record.
pub const VERSION: u32 = 1;

/// The opening of a session run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Session {
    /// [`VERSION`].
    pub version: u32,
    /// Who takes part.
    pub participant: String,
    /// The scenarios, in the plan's order.
    pub scenarios: Vec<String>,
    /// The seed of the presentation orders.
    pub seed: u64,
    /// Classification rounds.
    pub rounds: u32,
    /// Presentations of each stimulus per round.
    pub repeats: u32,
    /// True if the Self-Assessment Manikin round follows the classification rounds.
    pub sam: bool,
    /// Seconds since the Unix epoch, host clock.
    pub started: u64,
    /// True if this run continues an earlier one.
    pub resumed: bool,
}

/// One answered trial.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialRecord {
    /// Who answered.
    pub participant: String,
    /// From 1; the Self-Assessment Manikin round is the last.
    pub round: u32,
    /// From 1 within the round.
    pub position: u32,
    /// The stimulus's scenario.
    pub stimulus: String,
    /// The bank slot played.
    pub slot: u8,
    /// The device tick when the slot started.
    pub start_tick: u32,
    /// The device tick when it finished (`None` if the end was not heard).
    pub end_tick: Option<u32>,
    /// Times the stimulus was played (replays included).
    pub plays: u32,
    /// The probabilities, normalised, in the scenarios' order (classification rounds).
    pub p: Option<Vec<f64>>,
    /// Valence, 1 to 9 (Self-Assessment Manikin round).
    pub valence: Option<f64>,
    /// Arousal, 1 to 9 (Self-Assessment Manikin round).
    pub arousal: Option<f64>,
    /// Seconds from the end of the stimulus to the answer, host clock.
    pub response_s: f64,
}

/// Something else that happened, kept for the record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EventRecord {
    /// What (a short machine word: `refused`, `acclimation`, `done`).
    pub what: String,
    /// The details.
    pub detail: String,
}

/// One line of the log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Record {
    /// A run of the session begins.
    Session(Session),
    /// A trial was answered.
    Trial(TrialRecord),
    /// Anything else.
    Event(EventRecord),
}

impl Record {
    /// The record as one line, newline included.
    pub fn line(&self) -> String {
        // A record of plain fields always serialises.
        let mut s = serde_json::to_string(self).unwrap_or_default();
        s.push('\n');
        s
    }
}

/// The records of a log. A last line without its newline is the write a crash cut
/// short and is skipped; any other line that does not parse is an error.
pub fn records(text: &str) -> Result<Vec<Record>, DataError> {
    let complete = match text.rfind('\n') {
        Some(i) => &text[..=i],
        None => "",
    };
    let mut out = Vec::new();
    for (i, l) in complete.lines().enumerate() {
        if l.trim().is_empty() {
            continue;
        }
        let r = serde_json::from_str(l).map_err(|source| DataError::Json {
            line: i + 1,
            source,
        })?;
        out.push(r);
    }
    Ok(out)
}

/// The response set of a log.
pub fn read(text: &str) -> Result<Responses, DataError> {
    let mut scenarios: Option<Vec<String>> = None;
    let mut trials = Vec::new();
    for (i, r) in records(text)?.into_iter().enumerate() {
        let line = i + 1;
        match r {
            Record::Session(s) => match &scenarios {
                Some(first) if *first != s.scenarios => {
                    return Err(DataError::Scenarios {
                        first: first.clone(),
                        other: s.scenarios,
                    })
                }
                _ => scenarios = Some(s.scenarios),
            },
            Record::Trial(t) => {
                let names = scenarios.as_ref().ok_or_else(|| DataError::Line {
                    line,
                    problem: "a trial before any session record".into(),
                })?;
                let stimulus =
                    names
                        .iter()
                        .position(|s| *s == t.stimulus)
                        .ok_or_else(|| DataError::Line {
                            line,
                            problem: format!("stimulus {:?} is none of the scenarios", t.stimulus),
                        })?;
                let probabilities = match t.p {
                    Some(p) if p.len() != names.len() => {
                        return Err(DataError::Line {
                            line,
                            problem: format!(
                                "{} probabilities for {} scenarios",
                                p.len(),
                                names.len()
                            ),
                        })
                    }
                    Some(p) => Some(
                        crate::data::normalise(&p)
                            .map_err(|problem| DataError::Line { line, problem })?,
                    ),
                    None => None,
                };
                trials.push(Trial {
                    participant: t.participant,
                    round: t.round,
                    position: t.position,
                    stimulus,
                    probabilities,
                    valence: t.valence,
                    arousal: t.arousal,
                });
            }
            Record::Event(_) => {}
        }
    }
    let scenarios = scenarios.ok_or_else(|| DataError::Shape("no session record".into()))?;
    Ok(Responses { scenarios, trials })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn session() -> Record {
        Record::Session(Session {
            version: VERSION,
            participant: "p1".into(),
            scenarios: vec!["a".into(), "b".into()],
            seed: 1,
            rounds: 1,
            repeats: 1,
            sam: false,
            started: 0,
            resumed: false,
        })
    }

    fn trial() -> Record {
        Record::Trial(TrialRecord {
            participant: "p1".into(),
            round: 1,
            position: 1,
            stimulus: "b".into(),
            slot: 1,
            start_tick: 10,
            end_tick: Some(20),
            plays: 1,
            p: Some(vec![0.25, 0.75]),
            valence: None,
            arousal: None,
            response_s: 1.5,
        })
    }

    #[test]
    fn a_cut_last_line_is_skipped() {
        let mut text = session().line() + &trial().line();
        let whole = read(&text).unwrap();
        assert_eq!(whole.trials.len(), 1);
        assert_eq!(whole.trials[0].stimulus, 1);
        text.push_str(&trial().line()[..20]);
        assert_eq!(read(&text).unwrap(), whole);
    }

    #[test]
    fn a_bad_line_in_the_middle_is_an_error() {
        let text = session().line() + "{\"kind\":\n" + &trial().line();
        assert!(matches!(read(&text), Err(DataError::Json { line: 2, .. })));
    }
}
