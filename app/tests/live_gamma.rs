#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! A GenICam camera's gamma correction reaches the controller as the
//! camera's tone curve. Aravis's fake cameras have no gamma feature, so
//! they are described here by Aravis's own GenICam XML (taken from the
//! installed library with `gresource`, which libaravis-dev brings) with
//! `GammaEnable` and `Gamma` added, through `RIGVIEW_FAKE_GENICAM`.

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
fn a_fake_camera_with_gamma_correction_is_read_through_its_curve() {
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
    let with_gamma = |enable: u8| {
        xml.replace(
            end,
            &format!(
                "\t<Boolean Name=\"GammaEnable\" NameSpace=\"Standard\">\n\
                 \t\t<Value>{enable}</Value>\n\
                 \t</Boolean>\n\
                 \t<Float Name=\"Gamma\" NameSpace=\"Standard\">\n\
                 \t\t<Value>0.45</Value>\n\
                 \t\t<Min>0.1</Min>\n\
                 \t\t<Max>4.0</Max>\n\
                 \t</Float>\n\
                 {end}"
            ),
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let genicam = dir.path().join("fake-with-gamma.xml");
    std::fs::write(&genicam, with_gamma(1)).unwrap();
    let text = live(dir.path(), Some(&genicam));
    // 1 / 0.45 = 2.22, for each of the four cameras.
    let lines = text
        .lines()
        .filter(|l| l.contains("gamma correction on: frames read through a tone curve of 2.22"))
        .count();
    assert_eq!(lines, 4, "{text}");
    // Gamma correction off: linear frames.
    let off = dir.path().join("fake-gamma-off.xml");
    std::fs::write(&off, with_gamma(0)).unwrap();
    let text = live(dir.path(), Some(&off));
    assert!(!text.contains("gamma correction on"), "{text}");
    assert!(text.contains("fake cameras described by"), "{text}");
    // Aravis's own description: no gamma, linear frames.
    let plain = live(dir.path(), None);
    assert!(!plain.contains("gamma correction on"), "{plain}");
    assert!(plain.contains("open,"), "{plain}");
}
