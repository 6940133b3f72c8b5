//! The study plan (TOML): the scenarios with their bank slots and prompts, the
//! rounds, and the seed of the orders. Every mistake is named by its key.

use std::path::{Path, PathBuf};

use serde::Deserialize;

/// One scenario as the plan file writes it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioFile {
    name: String,
    slot: u8,
    prompt: String,
    audio: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlanFile {
    seed: u64,
    #[serde(default = "three")]
    rounds: u32,
    #[serde(default = "one")]
    repeats: u32,
    #[serde(default = "yes")]
    sam: bool,
    #[serde(default = "yes")]
    acclimation: bool,
    #[serde(default)]
    replay: bool,
    #[serde(default = "pause")]
    retry_pause_s: f64,
    scenario: Vec<ScenarioFile>,
}

fn three() -> u32 {
    3
}
fn one() -> u32 {
    1
}
fn yes() -> bool {
    true
}
fn pause() -> f64 {
    5.0
}

/// A scenario of a checked plan.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Its name (the report's row and column).
    pub name: String,
    /// The bank slot of its stimulus.
    pub slot: u8,
    /// The toucher prompt the participant reads.
    pub prompt: String,
    /// The prompt's recording, if any: its bytes and MIME type.
    pub audio: Option<(Vec<u8>, &'static str)>,
}

/// A checked plan.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Seeds the presentation orders.
    pub seed: u64,
    /// Classification rounds.
    pub rounds: u32,
    /// Presentations of each stimulus per round.
    pub repeats: u32,
    /// A Self-Assessment Manikin round after the classification rounds.
    pub sam: bool,
    /// Each stimulus once, unlabelled, before the rounds.
    pub acclimation: bool,
    /// The participant may replay a stimulus before answering.
    pub replay: bool,
    /// Pause before a refused stimulus is tried again, s.
    pub retry_pause_s: f64,
    /// The scenarios, in order.
    pub scenarios: Vec<Scenario>,
}

/// A plan mistake: the file, the key and the problem.
fn mistake(path: &Path, key: &str, problem: impl std::fmt::Display) -> anyhow::Error {
    crate::cli::report::usage(format!("{}: key `{key}`: {problem}", path.display()))
}

/// The key a TOML error points at: the `name = ` of its line or its table's header,
/// with the field a "missing field" error names; `?` when neither is known.
fn key_at(text: &str, e: &toml::de::Error) -> String {
    let field = e
        .message()
        .strip_prefix("missing field `")
        .and_then(|r| r.split('`').next());
    let line = e.span().map_or("", |span| {
        let start = text[..span.start.min(text.len())]
            .rfind('\n')
            .map_or(0, |i| i + 1);
        text[start..].lines().next().unwrap_or("").trim()
    });
    let header = line
        .starts_with('[')
        .then(|| line.trim_matches(['[', ']']).trim());
    let key = match line.split_once('=') {
        _ if line.starts_with('#') => None,
        Some((k, _)) if header.is_none() => Some(k.trim()),
        _ => header,
    };
    match (key, field) {
        (Some(h), Some(f)) if header.is_some() => format!("{h}.{f}"),
        (_, Some(f)) => f.to_string(),
        (Some(k), None) => k.to_string(),
        (None, None) => "?".into(),
    }
}

impl Plan {
    /// Reads and checks `path`; a mistake is a usage error (exit status 2).
    pub fn load(path: &Path) -> anyhow::Result<Plan> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| crate::cli::report::usage(format!("{}: {e}", path.display())))?;
        let f: PlanFile = toml::from_str(&text).map_err(|e| {
            let what = e.message().lines().next().unwrap_or("").to_string();
            mistake(path, &key_at(&text, &e), what)
        })?;
        if f.scenario.len() < 2 {
            return Err(mistake(
                path,
                "scenario",
                "at least two [[scenario]] tables are needed",
            ));
        }
        for (key, v, lo, hi) in [("rounds", f.rounds, 0, 20), ("repeats", f.repeats, 1, 20)] {
            if !(lo..=hi).contains(&v) {
                return Err(mistake(path, key, format!("{v} is not in {lo}..={hi}")));
            }
        }
        if f.rounds == 0 && !f.sam {
            return Err(mistake(
                path,
                "rounds",
                "0 rounds and no sam round: nothing to ask",
            ));
        }
        if !(0.0..=600.0).contains(&f.retry_pause_s) {
            return Err(mistake(path, "retry_pause_s", "must be 0 to 600 seconds"));
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut scenarios: Vec<Scenario> = Vec::new();
        for (i, s) in f.scenario.into_iter().enumerate() {
            let at = |k: &str| format!("scenario[{i}].{k}");
            let ok_name = !s.name.is_empty()
                && s.name
                    .chars()
                    .all(|c| c.is_alphanumeric() || c == '_' || c == '-');
            if !ok_name {
                return Err(mistake(
                    path,
                    &at("name"),
                    format!("{:?}: use letters, digits, _ and -", s.name),
                ));
            }
            if scenarios.iter().any(|o| o.name == s.name) {
                return Err(mistake(
                    path,
                    &at("name"),
                    format!("{:?} is named twice", s.name),
                ));
            }
            if let Some(o) = scenarios.iter().find(|o| o.slot == s.slot) {
                return Err(mistake(
                    path,
                    &at("slot"),
                    format!("slot {} is {:?}'s too", s.slot, o.name),
                ));
            }
            let audio = match s.audio {
                Some(a) => {
                    let p = dir.join(&a);
                    let bytes = std::fs::read(&p).map_err(|e| {
                        mistake(path, &at("audio"), format!("{}: {e}", p.display()))
                    })?;
                    let mime = match p.extension().and_then(|e| e.to_str()) {
                        Some("mp3") => "audio/mpeg",
                        Some("ogg") => "audio/ogg",
                        Some("wav") => "audio/wav",
                        _ => {
                            return Err(mistake(
                                path,
                                &at("audio"),
                                "use a .wav, .mp3 or .ogg file",
                            ))
                        }
                    };
                    Some((bytes, mime))
                }
                None => None,
            };
            scenarios.push(Scenario {
                name: s.name,
                slot: s.slot,
                prompt: s.prompt,
                audio,
            });
        }
        Ok(Plan {
            seed: f.seed,
            rounds: f.rounds,
            repeats: f.repeats,
            sam: f.sam,
            acclimation: f.acclimation,
            replay: f.replay,
            retry_pause_s: f.retry_pause_s,
            scenarios,
        })
    }

    /// The scenario names.
    pub fn names(&self) -> Vec<String> {
        self.scenarios.iter().map(|s| s.name.clone()).collect()
    }

    /// Every trial of `participant`'s session, in order: (round, position, scenario).
    /// Round `rounds + 1` is the Self-Assessment Manikin round.
    pub fn trials(&self, participant: &str) -> Vec<(u32, u32, usize)> {
        let n = self.scenarios.len();
        let last = self.rounds + u32::from(self.sam);
        let mut out = Vec::new();
        for round in 1..=last {
            let per = if round > self.rounds { 1 } else { self.repeats };
            let mut order = Vec::new();
            for rep in 0..per {
                let seed_round = round * 100 + rep;
                order.extend(touchc_study::order::round_order(
                    self.seed,
                    participant,
                    seed_round,
                    n,
                ));
            }
            for (pos, s) in order.into_iter().enumerate() {
                out.push((round, pos as u32 + 1, s));
            }
        }
        out
    }

    /// The acclimation order (each stimulus once).
    pub fn acclimation_order(&self, participant: &str) -> Vec<usize> {
        touchc_study::order::round_order(self.seed, participant, 0, self.scenarios.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(rounds: u32, repeats: u32, sam: bool) -> Plan {
        Plan {
            seed: 3,
            rounds,
            repeats,
            sam,
            acclimation: true,
            replay: false,
            retry_pause_s: 1.0,
            scenarios: (0..4)
                .map(|i| Scenario {
                    name: format!("s{i}"),
                    slot: i,
                    prompt: String::new(),
                    audio: None,
                })
                .collect(),
        }
    }

    #[test]
    fn every_round_presents_each_stimulus_repeats_times_then_the_manikin_round_once() {
        let p = plan(3, 2, true);
        let t = p.trials("p01");
        assert_eq!(t.len(), 3 * 2 * 4 + 4);
        for round in 1..=4u32 {
            let mut s: Vec<usize> = t.iter().filter(|x| x.0 == round).map(|x| x.2).collect();
            let positions: Vec<u32> = t.iter().filter(|x| x.0 == round).map(|x| x.1).collect();
            assert_eq!(positions, (1..=s.len() as u32).collect::<Vec<_>>());
            s.sort();
            let per = if round == 4 { 1 } else { 2 };
            assert_eq!(s, (0..4).flat_map(|i| vec![i; per]).collect::<Vec<_>>());
        }
        // The same participant gets the same orders; another, others.
        assert_eq!(t, p.trials("p01"));
        assert_ne!(t, p.trials("p02"));
        assert!(plan(2, 1, false).trials("p01").iter().all(|x| x.0 <= 2));
    }
}
