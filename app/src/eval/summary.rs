//! The evaluation's summary: one row per strategy with a headline figure
//! of each experiment it ran in, as the report's first table and as
//! Markdown (`headline.md`, for a README or a report of one's own).

use std::fmt::Write as _;

use super::panorama_seams::PanoramaStats;
use super::strategy::EvalStrategy;
use super::Results;

/// The columns: what each figure is, with its unit.
pub const COLUMNS: [&str; 9] = [
    "steps of light: frames to settle (median)",
    "steps of light: largest overshoot (EV)",
    "settled M / best (mean)",
    "settled: corners tracked frame to frame (mean per camera)",
    "settled: corners matched across an overlap (mean)",
    "settled: valid stereo disparities (share, mean over pairs)",
    "surround: mean abs log2 r_ij in the images (EV)",
    "surround: as the view shows it (EV)",
    "panorama: mean abs log2 r_ij, matched patches (EV)",
];

/// What a cell shows for a strategy an experiment did not run.
pub const NOT_RUN: &str = "·";

/// Per strategy that ran anywhere, its cells (see [`COLUMNS`]).
pub fn rows(r: &Results) -> Vec<(EvalStrategy, Vec<String>)> {
    let warmup = r.plan.seams.warmup;
    let cell = |v: Option<f64>, fmt: &dyn Fn(f64) -> String| match v {
        Some(v) if v.is_finite() => fmt(v),
        _ => NOT_RUN.to_string(),
    };
    EvalStrategy::ALL
        .iter()
        .filter_map(|&s| {
            let steps: Vec<_> = r.steps.rows.iter().filter(|x| x.strategy == s).collect();
            let settle = (!steps.is_empty()).then(|| {
                let mut f: Vec<f64> = steps
                    .iter()
                    .map(|x| x.response.settle_frames as f64)
                    .collect();
                crate::report::quantile(&mut f, 0.5)
            });
            let overshoot = (!steps.is_empty()).then(|| {
                steps
                    .iter()
                    .map(|x| x.response.overshoot_ev)
                    .fold(0.0, f64::max)
            });
            let m = Some(r.sweep.mean_fraction(s));
            let tracked = Some(r.sweep.mean_tracked(s));
            let inliers = Some(r.sweep.mean_inliers(s));
            let stereo = Some(r.sweep.mean_stereo(s));
            let seams: Vec<_> = r
                .seams
                .runs
                .iter()
                .filter(|x| x.strategy == s)
                .map(|x| x.stats(warmup))
                .collect();
            let mean = |f: fn(&super::seams::SeamStats) -> f64| {
                (!seams.is_empty()).then(|| seams.iter().map(f).sum::<f64>() / seams.len() as f64)
            };
            let panorama: Vec<_> = r.panorama.runs.iter().filter(|x| x.strategy == s).collect();
            let panorama = (!panorama.is_empty()).then(|| PanoramaStats::of(panorama).mean);
            let cells = vec![
                cell(settle, &|v| format!("{v:.0}")),
                cell(overshoot, &|v| format!("{v:.2}")),
                cell(m, &|v| format!("{:.1} %", 100.0 * v)),
                cell(tracked, &|v| format!("{v:.0}")),
                cell(inliers, &|v| format!("{v:.0}")),
                cell(stereo, &|v| format!("{:.1} %", 100.0 * v)),
                cell(mean(|x| x.mean_images), &|v| format!("{v:.2}")),
                cell(mean(|x| x.mean_view), &|v| format!("{v:.2}")),
                cell(panorama, &|v| format!("{v:.2}")),
            ];
            cells.iter().any(|c| c != NOT_RUN).then_some((s, cells))
        })
        .collect()
}

/// The summary as shown: the columns with a figure for some strategy (a
/// rig without a stereo pair has no stereo column, a bracket sequence no
/// panorama column) and every row's cells in them.
pub fn shown(r: &Results) -> (Vec<&'static str>, Vec<(EvalStrategy, Vec<String>)>) {
    let rows = rows(r);
    let keep: Vec<bool> = (0..COLUMNS.len())
        .map(|c| rows.iter().any(|(_, cells)| cells[c] != NOT_RUN))
        .collect();
    let columns = COLUMNS
        .iter()
        .zip(&keep)
        .filter_map(|(c, &k)| k.then_some(*c))
        .collect();
    let rows = rows
        .into_iter()
        .map(|(s, cells)| {
            let cells = cells
                .into_iter()
                .zip(&keep)
                .filter_map(|(c, &k)| k.then_some(c))
                .collect();
            (s, cells)
        })
        .collect();
    (columns, rows)
}

/// The summary as a Markdown table ([`shown`]'s columns).
pub fn markdown(r: &Results) -> String {
    let (columns, rows) = shown(r);
    let mut m = String::from("| strategy |");
    for c in &columns {
        let _ = write!(m, " {c} |");
    }
    m += "\n| --- |";
    m += &" ---: |".repeat(columns.len());
    m.push('\n');
    for (s, cells) in rows {
        let _ = writeln!(m, "| {} | {} |", s.label(), cells.join(" | "));
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_strategy_is_summarised_once() {
        let mut seen = EvalStrategy::ALL.to_vec();
        seen.sort_by_key(|s| s.key());
        seen.dedup();
        assert_eq!(seen.len(), EvalStrategy::ALL.len());
        for list in [
            &EvalStrategy::STEPS[..],
            &EvalStrategy::SETTLED[..],
            &EvalStrategy::SEAMS[..],
            &EvalStrategy::PANORAMA[..],
        ] {
            assert!(list.iter().all(|s| EvalStrategy::ALL.contains(s)));
        }
    }
}
