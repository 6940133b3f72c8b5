//! Stages 0-3 alone, on the whole recording: what `touchc track` runs. The same driver
//! as the compile's ([`track_cropped`]), without a crop.

use touchc_input::recording::Recording;
use touchc_model::config::{Metadata, MetadataOverrides, Sampling, ValidConfig};
use touchc_model::crop::Crop;
use touchc_tracking::scene::track_cropped;
use touchc_tracking::track::TrackOutput;

use crate::compile::CompileError;

/// Stages 0-3: tare, upsample and blur, detect, track, at the rate and pitch of the file
/// or the config, keeping the blurred movie and the detections. What the config's knobs
/// become at the recording's sampling is checked first.
pub fn track(rec: &Recording, cfg: &ValidConfig) -> Result<TrackOutput, CompileError> {
    // The compile's driver on the whole recording, keeping the blurred movie.
    track_whole(rec, cfg, &MetadataOverrides::default(), true)
}

/// [`track`] with the rate and pitch of `overrides` where given (`--rate`, `--pitch-mm`),
/// streaming through the frames as the compile does: the same
/// statistics and trajectories, bit for bit, but neither the blurred movie (`blurred`
/// has no frames) nor the detections are kept, so memory follows the touch, not the
/// recording's length (an hour's movie is 4.7 GB).
pub fn track_streaming(
    rec: &Recording,
    cfg: &ValidConfig,
    overrides: &MetadataOverrides,
) -> Result<TrackOutput, CompileError> {
    track_whole(rec, cfg, overrides, false)
}

/// Stages 0-3 on the whole recording (no crop), keeping the scene or not.
fn track_whole(
    rec: &Recording,
    cfg: &ValidConfig,
    overrides: &MetadataOverrides,
    keep_scene: bool,
) -> Result<TrackOutput, CompileError> {
    let sampling = Sampling::new(
        &Metadata::resolve(overrides, &rec.file_metadata(), cfg),
        cfg,
    );
    let (_, rows, cols) = rec.dim();
    cfg.validate_for(&sampling, (rows, cols))?;
    let tared = rec.tare(&cfg.input, &sampling)?;
    let whole = Crop::whole(tared.dim());
    let (tracked, _) = track_cropped(
        tared.view(),
        &whole,
        cfg,
        &sampling,
        keep_scene,
        &mut |_| {},
    )?;
    Ok(tracked)
}
