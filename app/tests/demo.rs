#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The `rigview` binary: the default command opens the window on the
//! simulated rig; `demo` prints the closed loop.

use std::process::Command;

fn rigview(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigview"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The lines of frame sets: they start with the set's number.
fn set_lines(stdout: &str) -> Vec<&str> {
    stdout
        .lines()
        .filter(|l| {
            l.split_whitespace()
                .next()
                .is_some_and(|w| w.parse::<u64>().is_ok())
        })
        .collect()
}

/// Arguments: `words`, then `paths`.
fn os(words: &[&str], paths: &[&std::path::Path]) -> Vec<std::ffi::OsString> {
    words
        .iter()
        .map(std::ffi::OsString::from)
        .chain(paths.iter().map(|p| p.as_os_str().to_owned()))
        .collect()
}

/// An X server of its own (Xvfb, which the set-up installs), stopped when
/// dropped.
struct Xvfb {
    child: std::process::Child,
    display: String,
}

impl Xvfb {
    /// Starts Xvfb on a free display and waits until it accepts
    /// connections: with `-displayfd`, Xvfb picks the display and writes
    /// its number only once it is ready.
    fn start() -> Self {
        use std::io::BufRead;
        let mut child = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "1600x1000x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("Xvfb is missing: scripts/setup installs it");
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let n: u32 = line
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("Xvfb did not say its display: {line:?}"));
        Self {
            child,
            display: format!(":{n}"),
        }
    }
}

impl Xvfb {
    /// Runs `rigview` with `args` on this display (and no Wayland's), and
    /// returns whether it succeeded and its stderr.
    fn run(&self, args: &[std::ffi::OsString]) -> (bool, String) {
        let out = Command::new(env!("CARGO_BIN_EXE_rigview"))
            .args(args)
            .env("DISPLAY", &self.display)
            .env_remove("WAYLAND_DISPLAY")
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn the_default_command_opens_the_window_on_the_simulated_rig() {
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let settings = dir.path().join("settings.yaml");
    let (ok, stderr) = x.run(&os(&["--quit-after", "8", "--settings"], &[&settings]));
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("source: simulated rig \"reference\" (4 × 1288×964"),
        "{stderr}"
    );
    // The summary the window prints when it closes: sets went through the
    // pipeline and reached the screen.
    let processed = stderr
        .split_once(" processed, ")
        .and_then(|(a, _)| a.rsplit(' ').next())
        .and_then(|n| n.parse::<u64>().ok())
        .unwrap_or(0);
    assert!(processed >= 5, "{stderr}");
    assert!(stderr.contains("set ready → displayed"), "{stderr}");
    // The settings were saved on exit.
    let text = std::fs::read_to_string(&settings).unwrap();
    assert!(text.contains("format: rigview-settings"), "{text}");
}

/// The bowl view in the real window, drawn on the GPU through the glow
/// paint callback (Mesa's software GL under Xvfb): the window says how many
/// pictures it drew, and its screenshot shows the bowl.
#[test]
fn the_window_draws_the_bowl_on_the_gpu() {
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let settings = dir.path().join("settings.yaml");
    std::fs::write(&settings, "window:\n  bowl_renderer: gpu\n").unwrap();
    let shot = dir.path().join("bowl.png");
    let words = ["run", "--view", "bowl", "--viewpoint", "behind-left"];
    let args = [
        os(&words, &[]),
        os(&["--screenshot-after", "7", "--screenshot"], &[&shot]),
        os(&["--settings"], &[&settings]),
    ]
    .concat();
    let (ok, stderr) = x.run(&args);
    assert!(ok, "{stderr}");
    let pictures = stderr
        .split_once("bowl on the GPU: ")
        .and_then(|(_, rest)| rest.split(' ').next())
        .and_then(|n| n.parse::<u64>().ok())
        .unwrap_or(0);
    assert!(pictures >= 3, "{stderr}");
    // The view (the middle of the window's upper half) shows a picture,
    // not a blank or a single colour.
    let image = image::open(&shot).unwrap().to_luma8();
    let (w, h) = image.dimensions();
    let mut levels = [0u32; 256];
    for y in h / 8..h / 2 {
        for x in w / 4..3 * w / 4 {
            levels[usize::from(image.get_pixel(x, y).0[0])] += 1;
        }
    }
    let used = levels.iter().filter(|&&n| n > 50).count();
    assert!(used > 40, "{used} grey levels in the view");
    // Auto (the default) on a software GL: the CPU composes the bowl.
    std::fs::write(&settings, "window:\n  bowl_renderer: auto\n").unwrap();
    let words = ["run", "--view", "bowl", "--quit-after", "4", "--settings"];
    let args = os(&words, &[&settings]);
    let (ok, stderr) = x.run(&args);
    assert!(ok, "{stderr}");
    assert!(!stderr.contains("bowl on the GPU"), "{stderr}");
}

#[test]
fn without_a_display_the_window_says_what_to_run_instead() {
    let out = Command::new(env!("CARGO_BIN_EXE_rigview"))
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("no display"), "{stderr}");
    assert!(stderr.contains("rigview run --headless"), "{stderr}");
}

#[test]
fn the_demo_takes_scenarios_and_options() {
    let (ok, stdout, stderr) = rigview(&[
        "demo",
        "--scenario",
        "tunnel",
        "--frames",
        "3",
        "--scale",
        "0.25",
        "--bits",
        "12",
        "--law",
        "fast",
        "--strategy",
        "single",
        "--meter",
        "full",
    ]);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("322×241 Mono12"), "{stdout}");
    assert_eq!(set_lines(&stdout).len(), 3, "{stdout}");
}

#[test]
fn a_bad_scenario_is_a_clear_error() {
    let (ok, _, stderr) = rigview(&["demo", "--scenario", "no-such-scenario.sim.yaml"]);
    assert!(!ok);
    assert!(stderr.contains("no-such-scenario.sim.yaml"), "{stderr}");
    let dir = std::env::temp_dir().join(format!("rigview-demo-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.sim.yaml");
    std::fs::write(
        &file,
        "format: rigview-sim\nversion: 1\nscene: {sun: {elevation_deg: 120}}\n",
    )
    .unwrap();
    let (ok, _, stderr) = rigview(&["demo", "--scenario", file.to_str().unwrap()]);
    assert!(!ok);
    assert!(
        stderr.contains("bad.sim.yaml") && stderr.contains("scene.sun.elevation_deg"),
        "{stderr}"
    );
    let (ok, _, stderr) = rigview(&["demo", "--latency", "3", "--scale", "0.25"]);
    assert!(!ok);
    assert!(stderr.contains("latency_frames"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A reader that stops early (`rigview demo | head -1`) ends the demo
/// quietly: success, and nothing on stderr.
#[test]
fn a_reader_that_stops_early_ends_the_demo_quietly() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_rigview"))
        .args(["demo", "--scale", "0.25", "--frames", "2000"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(!first.is_empty());
    // The pipe's reader is gone; the demo writes on into it.
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
    assert!(stderr.trim().is_empty(), "{stderr}");
}
