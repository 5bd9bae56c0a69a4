//! `rigview recording info|repair`: what a recording holds, and a
//! recording that was not closed rewritten with its indexes.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;

/// `rigview recording info`: duration, sets, topics and drops.
pub fn info(file: &Path) -> Result<String> {
    let i = rigview_record::info(file)?;
    let cameras: Vec<_> = i
        .meta
        .cameras
        .iter()
        .map(|c| {
            format!(
                "{} ({}×{} {})",
                c.name,
                c.width,
                c.height,
                c.format.genicam_name()
            )
        })
        .collect();
    let mut s = format!(
        "{}\n  recorded by rigview {} from {}\n  cameras: {}\n  {} complete sets over {:.2} s; {} sets dropped while recording\n",
        file.display(),
        i.meta.version,
        i.meta.source,
        cameras.join(", "),
        i.sets,
        i.duration_s(),
        i.dropped,
    );
    let rig = if i.meta.rig_yaml.is_some() {
        "attached (rig.yaml)"
    } else {
        "none"
    };
    let _ = writeln!(s, "  calibration: {rig}");
    match (&i.end, &i.tail) {
        (Some(e), None) => {
            let _ = writeln!(s, "  ended: {}", e.stopped);
        }
        (_, Some(t)) => {
            let _ = writeln!(
                s,
                "  NOT CLOSED ({t}): replays up to its last complete set; \
                 `rigview recording repair` rewrites it with an index"
            );
        }
        (None, None) => s += "  ended without its end record\n",
    }
    s += "  topics:\n";
    for (topic, (schema, n)) in &i.topics {
        let _ = writeln!(s, "    {topic}  {schema}  {n} messages");
    }
    Ok(s)
}

/// `rigview recording repair`: rewrites `input` with its indexes.
pub fn repair(input: &Path, output: &Path) -> Result<String> {
    if input == output {
        anyhow::bail!(
            "repair writes a new file: give an output other than {}",
            input.display()
        );
    }
    let r = rigview_record::repair(input, output)?;
    let tail = r
        .tail
        .map(|t| format!("; the input ended early ({t})"))
        .unwrap_or_default();
    Ok(format!(
        "{} → {}: {} complete sets{tail}",
        input.display(),
        output.display(),
        r.sets
    ))
}
