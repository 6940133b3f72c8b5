//! A labelled data set: a folder with one subfolder of recordings per class, or a CSV
//! manifest `path,label[,group]` (the group is the person who touched; with groups,
//! folds keep each person whole).
//!
//! Recordings are read by the input stage ([`Recording`]) and kept as `f32` frames with
//! NaN (no cell) set to 0, as the paper padded its non-rectangular sleeve. One data set
//! shares one sensor shape; recordings may differ in length.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ndarray::Array3;
use rayon::prelude::*;
use touchc_input::recording::Recording;
use touchc_model::config::{MetadataOverrides, Sampling};

use crate::SelectError;

/// One recording of a data set, before it is loaded.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// The file.
    pub path: PathBuf,
    /// Index of its class in [`Listing::classes`].
    pub label: usize,
    /// The person (or session) it came from, if the manifest says.
    pub group: Option<String>,
}

/// The recordings of a data set and their classes, not yet loaded.
#[derive(Debug, Clone, PartialEq)]
pub struct Listing {
    /// The folder or manifest the listing was read from.
    pub source: PathBuf,
    /// Class names: a folder's subfolders in name order, or a manifest's labels in
    /// order of first appearance.
    pub classes: Vec<String>,
    /// Every recording, in folder-name or manifest order.
    pub items: Vec<Item>,
}

/// A recording loaded for scoring.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Frames `[T, rows, cols]`, psi, 0 where the sensor has no cell.
    pub frames: Array3<f32>,
    /// Frame rate, Hz (the override, else the file's, else the paper's 20 Hz).
    pub rate_hz: f64,
    /// Cell pitch, mm (likewise).
    pub pitch_mm: f64,
}

/// A loaded data set: the listing and every recording's frames, in its order.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// Classes and items.
    pub listing: Listing,
    /// The recordings, one per item.
    pub samples: Vec<Sample>,
}

/// File names read as recordings in a class folder.
fn is_recording(path: &Path) -> bool {
    matches!(
        path.extension().and_then(|e| e.to_str()),
        Some("npy" | "npz")
    )
}

fn read_dir_sorted(dir: &Path) -> Result<Vec<PathBuf>, SelectError> {
    let io = |source| SelectError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let hidden = path
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with('.'));
        if !hidden {
            out.push(path);
        }
    }
    out.sort();
    Ok(out)
}

impl Listing {
    /// Reads a data set's listing: `source` is a folder of class subfolders, or a CSV
    /// manifest. Checks that there are two classes or more and none is empty.
    pub fn open(source: &Path) -> Result<Self, SelectError> {
        let listing = if source.is_dir() {
            Self::from_folder(source)?
        } else {
            let text = std::fs::read_to_string(source).map_err(|e| SelectError::Io {
                path: source.to_path_buf(),
                source: e,
            })?;
            Self::from_manifest(source, &text)?
        };
        listing.check_classes()?;
        Ok(listing)
    }

    fn from_folder(dir: &Path) -> Result<Self, SelectError> {
        let mut classes = Vec::new();
        let mut items = Vec::new();
        for sub in read_dir_sorted(dir)?.into_iter().filter(|p| p.is_dir()) {
            let label = classes.len();
            classes.push(sub.file_name().unwrap_or_default().to_string_lossy().into());
            for path in read_dir_sorted(&sub)?
                .into_iter()
                .filter(|p| p.is_file() && is_recording(p))
            {
                items.push(Item {
                    path,
                    label,
                    group: None,
                });
            }
        }
        Ok(Listing {
            source: dir.to_path_buf(),
            classes,
            items,
        })
    }

    /// Parses a manifest's text: `path,label[,group]` per line, paths relative to the
    /// manifest's folder; an optional header `path,label[,group]`, blank lines and
    /// `#` comments skipped. Either every line has a group or none has.
    pub fn from_manifest(manifest: &Path, text: &str) -> Result<Self, SelectError> {
        let base = manifest.parent().unwrap_or(Path::new(""));
        let bad = |line: usize, problem: String| SelectError::Manifest {
            path: manifest.to_path_buf(),
            line,
            problem,
        };
        let mut index: BTreeMap<String, usize> = BTreeMap::new();
        let mut classes = Vec::new();
        let mut items: Vec<Item> = Vec::new();
        for (n, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            if items.is_empty()
                && fields.first() == Some(&"path")
                && fields.get(1) == Some(&"label")
            {
                continue;
            }
            let (path, label, group) = match fields.as_slice() {
                [p, l] => (*p, *l, None),
                [p, l, g] => (*p, *l, Some(g.to_string())),
                _ => {
                    return Err(bad(
                        n + 1,
                        format!(
                            "expected path,label[,group], found {} field(s)",
                            fields.len()
                        ),
                    ))
                }
            };
            if path.is_empty() || label.is_empty() || group.as_ref().is_some_and(|g| g.is_empty()) {
                return Err(bad(n + 1, "an empty field".into()));
            }
            if let Some(first) = items.first() {
                if first.group.is_some() != group.is_some() {
                    return Err(bad(
                        n + 1,
                        "some lines have a group and some do not: give every line one or none"
                            .into(),
                    ));
                }
            }
            let next = classes.len();
            let label = *index.entry(label.to_string()).or_insert_with(|| {
                classes.push(label.to_string());
                next
            });
            items.push(Item {
                path: base.join(path),
                label,
                group,
            });
        }
        Ok(Listing {
            source: manifest.to_path_buf(),
            classes,
            items,
        })
    }

    fn check_classes(&self) -> Result<(), SelectError> {
        if let Some(class) =
            (0..self.classes.len()).find(|c| !self.items.iter().any(|i| i.label == *c))
        {
            return Err(SelectError::EmptyClass {
                data: self.source.clone(),
                class: self.classes[class].clone(),
            });
        }
        if self.classes.len() < 2 {
            return Err(SelectError::TooFewClasses {
                data: self.source.clone(),
                found: self.classes.len(),
                classes: self.classes.join(", "),
            });
        }
        Ok(())
    }

    /// True when every recording has a group.
    pub fn grouped(&self) -> bool {
        !self.items.is_empty() && self.items.iter().all(|i| i.group.is_some())
    }

    /// Loads every recording (in parallel), checking they share one sensor shape. The
    /// first error in listing order is returned, whatever order they were read in.
    pub fn load(self, overrides: &MetadataOverrides) -> Result<Dataset, SelectError> {
        let samples = self
            .items
            .par_iter()
            .map(|item| load_sample(&item.path, overrides))
            .collect::<Vec<_>>()
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?;
        check_shapes(
            self.items.iter().map(|i| i.path.display().to_string()),
            &samples,
        )?;
        Ok(Dataset {
            listing: self,
            samples,
        })
    }
}

/// Loads one recording for scoring.
pub fn load_sample(path: &Path, overrides: &MetadataOverrides) -> Result<Sample, SelectError> {
    let recording = Recording::load(path)?;
    Ok(sample_of(&recording, overrides))
}

/// A loaded recording as scored: NaN set to 0, its rate and pitch resolved.
pub fn sample_of(recording: &Recording, overrides: &MetadataOverrides) -> Sample {
    let file = recording.file_metadata();
    Sample {
        frames: recording
            .data()
            .mapv(|v| if v.is_nan() { 0.0 } else { v as f32 }),
        rate_hz: overrides
            .rate_hz
            .or(file.rate_hz)
            .unwrap_or(Sampling::PAPER.rate_hz),
        pitch_mm: overrides
            .pitch_mm
            .or(file.pitch_mm)
            .unwrap_or(Sampling::PAPER.pitch_mm),
    }
}

/// Checks that every sample has the first one's rows and columns.
pub fn check_shapes(
    names: impl Iterator<Item = String>,
    samples: &[Sample],
) -> Result<(), SelectError> {
    let mut first: Option<(String, usize, usize)> = None;
    for (name, s) in names.zip(samples) {
        let (_, r, c) = s.frames.dim();
        match &first {
            None => first = Some((name, r, c)),
            Some((f, r1, c1)) if (*r1, *c1) != (r, c) => {
                return Err(SelectError::MixedShapes {
                    first: f.clone(),
                    rows1: *r1,
                    cols1: *c1,
                    second: name,
                    rows2: r,
                    cols2: c,
                })
            }
            Some(_) => {}
        }
    }
    Ok(())
}

impl Dataset {
    /// Each recording's class index.
    pub fn labels(&self) -> Vec<usize> {
        self.listing.items.iter().map(|i| i.label).collect()
    }

    /// Each recording's group, when every one has a group.
    pub fn groups(&self) -> Option<Vec<String>> {
        self.listing.grouped().then(|| {
            self.listing
                .items
                .iter()
                .filter_map(|i| i.group.clone())
                .collect()
        })
    }
}
