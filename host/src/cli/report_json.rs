//! `touchc compile --report`: a compile's [`Report`] as JSON, its warnings worded as
//! on stderr and the input stage's also as values.

use serde::ser::{Serialize, SerializeStruct, Serializer};
use touchc_pipeline::compile::Report;

/// [`Report`] as the `--report` file holds it.
pub struct ReportJson<'a>(pub &'a Report);

impl Serialize for ReportJson<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // Every field by name, so a field added to the report fails to build here until
        // the file says where it goes.
        let Report {
            input,
            shape,
            name,
            transform,
            score,
            selected,
            trajectories,
            transforms,
            transforms_evaluated,
            transforms_inexact,
            trajectory_limit_reached,
            flow_work,
            flow_budget_reached,
            seconds,
            bytes,
            duration_s,
            bytes_per_second,
            rms_error_fs,
            max_error_fs,
            keyframe_period_ms,
            quant_shift,
            line_tolerance_fs,
            fit_scale,
            no_touch,
            crop,
            coverage,
            coverage_detail,
            misses,
            rendered_coverage,
            rendered_detail,
            shortfall,
            warnings,
            metadata,
            config,
            layout,
        } = self.0;
        let words: Vec<String> = warnings.iter().map(super::warning::describe).collect();
        let input_warnings: Vec<_> = self.0.input_warnings().collect();
        let mut r = s.serialize_struct("Report", 36)?;
        r.serialize_field("input", input)?;
        r.serialize_field("shape", shape)?;
        r.serialize_field("name", name)?;
        r.serialize_field("transform", transform)?;
        r.serialize_field("score", score)?;
        r.serialize_field("selected", selected)?;
        r.serialize_field("trajectories", trajectories)?;
        r.serialize_field("transforms", transforms)?;
        r.serialize_field("transforms_evaluated", transforms_evaluated)?;
        r.serialize_field("transforms_inexact", transforms_inexact)?;
        r.serialize_field("trajectory_limit_reached", trajectory_limit_reached)?;
        r.serialize_field("flow_work", flow_work)?;
        r.serialize_field("flow_budget_reached", flow_budget_reached)?;
        r.serialize_field("seconds", seconds)?;
        r.serialize_field("bytes", bytes)?;
        r.serialize_field("duration_s", duration_s)?;
        r.serialize_field("bytes_per_second", bytes_per_second)?;
        r.serialize_field("rms_error_fs", rms_error_fs)?;
        r.serialize_field("max_error_fs", max_error_fs)?;
        r.serialize_field("keyframe_period_ms", keyframe_period_ms)?;
        r.serialize_field("quant_shift", quant_shift)?;
        r.serialize_field("line_tolerance_fs", line_tolerance_fs)?;
        r.serialize_field("fit_scale", fit_scale)?;
        r.serialize_field("no_touch", no_touch)?;
        r.serialize_field("crop", crop)?;
        r.serialize_field("coverage", coverage)?;
        r.serialize_field("coverage_detail", coverage_detail)?;
        r.serialize_field("misses", misses)?;
        r.serialize_field("rendered_coverage", rendered_coverage)?;
        r.serialize_field("rendered_detail", rendered_detail)?;
        r.serialize_field("shortfall", shortfall)?;
        r.serialize_field("warnings", &words)?;
        r.serialize_field("input_warnings", &input_warnings)?;
        r.serialize_field("metadata", metadata)?;
        r.serialize_field("config", config)?;
        r.serialize_field("layout", layout)?;
        r.end()
    }
}
