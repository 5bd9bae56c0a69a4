#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! A GenICam camera's gamma correction and pixel lookup table reach the
//! controller as the camera's tone curve. Aravis's fake cameras have
//! neither, so they are described here by Aravis's own GenICam XML (taken
//! from the installed library with `gresource`, which libaravis-dev
//! brings) with `GammaEnable` and `Gamma`, `LUTEnable`, `LUTIndex` and
//! `LUTValue` (a table squaring its input, computed from the index by an
//! `IntSwissKnife`), and Basler's `BslColorSpace` added, through
//! `RIGVIEW_FAKE_GENICAM`.

use std::process::Command;

/// Runs `rigview live --fake --headless` for two seconds, with the fake
/// cameras' GenICam XML from `genicam` if given; its whole output.
fn live(dir: &std::path::Path, genicam: Option<&std::path::Path>) -> String {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_rigview"));
    cmd.args([
        "live",
        "--fake",
        "--headless",
        "--seconds",
        "2",
        "--scale",
        "0.25",
    ])
    .arg("--settings")
    .arg(dir.join("settings.yaml"));
    if let Some(g) = genicam {
        cmd.env(rigview::live::fake::FAKE_GENICAM_ENV, g);
    }
    let out = cmd.output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{text}");
    text
}

#[test]
fn a_fake_camera_with_gamma_correction_or_a_lookup_table_is_read_through_its_curve() {
    let libdir = Command::new("pkg-config")
        .args(["--variable=libdir", "aravis-0.8"])
        .output()
        .unwrap();
    let libdir = String::from_utf8(libdir.stdout).unwrap();
    let lib = std::path::Path::new(libdir.trim()).join("libaravis-0.8.so");
    let xml = Command::new("gresource")
        .arg("extract")
        .arg(&lib)
        .arg("/org/aravis/arv-fake-camera.xml")
        .output()
        .unwrap();
    assert!(xml.status.success(), "gresource extract {}", lib.display());
    let xml = String::from_utf8(xml.stdout).unwrap();
    let end = "</RegisterDescription>";
    assert!(xml.contains(end) && !xml.contains("\"Gamma\""));
    // A node of the description: its kind, name and lines inside.
    let node = |kind: &str, name: &str, lines: &[String]| {
        let inside: String = lines.iter().map(|l| format!("\t\t{l}\n")).collect();
        format!("\t<{kind} Name=\"{name}\" NameSpace=\"Standard\">\n{inside}\t</{kind}>\n")
    };
    let with = |gamma: u8, lut: u8, space: u8| {
        let range = |value: &str, max: &str| {
            vec![
                value.to_owned(),
                "<Min>0</Min>".to_owned(),
                format!("<Max>{max}</Max>"),
            ]
        };
        let nodes = [
            node(
                "Boolean",
                "GammaEnable",
                &[format!("<Value>{gamma}</Value>")],
            ),
            node(
                "Float",
                "Gamma",
                &[
                    "<Value>0.45</Value>".into(),
                    "<Min>0.1</Min>".into(),
                    "<Max>4.0</Max>".into(),
                ],
            ),
            node("Boolean", "LUTEnable", &[format!("<Value>{lut}</Value>")]),
            node(
                "Enumeration",
                "BslColorSpace",
                &[
                    "<EnumEntry Name=\"Off\"><Value>0</Value></EnumEntry>".into(),
                    "<EnumEntry Name=\"sRgb\"><Value>1</Value></EnumEntry>".into(),
                    format!("<Value>{space}</Value>"),
                ],
            ),
            node("Integer", "LUTIndex", &range("<Value>7</Value>", "1023")),
            node(
                "Integer",
                "LUTValue",
                &range("<pValue>LUTSquare</pValue>", "1023"),
            ),
            node(
                "IntSwissKnife",
                "LUTSquare",
                &[
                    "<pVariable Name=\"I\">LUTIndex</pVariable>".into(),
                    "<Formula>(I*I)/1023</Formula>".into(),
                ],
            ),
        ];
        xml.replace(end, &format!("{}{end}", nodes.concat()))
    };
    let dir = tempfile::tempdir().unwrap();
    let curve = |text: &str, p: &str| {
        text.lines()
            .filter(|l| {
                l.contains(&format!(
                    "gamma correction or lookup table on: frames read through a tone curve of {p}"
                ))
            })
            .count()
    };
    let run = |name: &str, gamma: u8, lut: u8, space: u8| {
        let genicam = dir.path().join(name);
        std::fs::write(&genicam, with(gamma, lut, space)).unwrap();
        live(dir.path(), Some(&genicam))
    };
    // 1 / 0.45 = 2.22, for each of the four cameras.
    let text = run("gamma.xml", 1, 0, 0);
    assert_eq!(curve(&text, "2.22"), 4, "{text}");
    // The table squares its input: light is the recorded value's root.
    let text = run("lut.xml", 0, 1, 0);
    assert_eq!(curve(&text, "0.50"), 4, "{text}");
    // Both: (L^0.45)² = L^0.9, so light is the recorded value to 1.11.
    let text = run("both.xml", 1, 1, 0);
    assert_eq!(curve(&text, "1.11"), 4, "{text}");
    // Basler's sRGB colour space (about 1/2.2), alone and on top of the
    // gamma (0.45 / 2.2: 4.89).
    let text = run("srgb.xml", 0, 0, 1);
    assert_eq!(curve(&text, "2.20"), 4, "{text}");
    let text = run("srgb-gamma.xml", 1, 0, 1);
    assert_eq!(curve(&text, "4.89"), 4, "{text}");
    // Neither on: linear frames.
    let text = run("off.xml", 0, 0, 0);
    assert!(!text.contains("lookup table on"), "{text}");
    assert!(text.contains("fake cameras described by"), "{text}");
    // Aravis's own description: no gamma, linear frames.
    let plain = live(dir.path(), None);
    assert!(!plain.contains("lookup table on"), "{plain}");
    assert!(plain.contains("open,"), "{plain}");
}
