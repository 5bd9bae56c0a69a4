//! Live capture over the GigE Vision protocol: four `arv-fake-gv-camera-0.8`
//! processes on loopback addresses 127.0.0.1 … 127.0.0.4, started and
//! stopped by the test. Run with `--nocapture` to see the figures.
//!
//! Needs: `arv-fake-gv-camera-0.8` (Debian's aravis-tools) and the loopback
//! addresses 127.0.0.2–4, which the test adds with `ip addr add … dev lo`
//! when they are missing (that needs root or CAP_NET_ADMIN) and removes
//! again. Without them it fails at once with a message saying so. The
//! scenarios share the addresses, so they run one after another.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use rigview::live::{CameraSpec, CaptureConfig, DeviceSpec, LiveSource, TriggerMode};
use rigview::logging::LogBuffer;
use rigview_core::exposure::NeighbourGraph;
use rigview_core::pipeline::{LockStep, ProcessingSettings, Processor, Strategy};
use rigview_core::source::{FrameSource, StreamState};

const ADDRESSES: [&str; 4] = ["127.0.0.1", "127.0.0.2", "127.0.0.3", "127.0.0.4"];
const FAKE_GV: &str = "arv-fake-gv-camera-0.8";

/// One scenario at a time: they use the same addresses and ports.
static SERIAL: Mutex<()> = Mutex::new(());

/// The loopback addresses this test added, removed again on drop.
struct Aliases(Vec<String>);

impl Aliases {
    fn ensure() -> Aliases {
        let shown = Command::new("ip")
            .args(["-o", "-4", "addr", "show", "dev", "lo"])
            .output()
            .unwrap_or_else(|e| {
                panic!("the GigE Vision test needs `ip` (Debian's iproute2) to set up loopback addresses: {e}")
            });
        let have = String::from_utf8_lossy(&shown.stdout).to_string();
        let mut added = Vec::new();
        for a in &ADDRESSES[1..] {
            if have.contains(&format!("inet {a}/")) {
                continue;
            }
            let out = Command::new("ip")
                .args(["addr", "add", &format!("{a}/32"), "dev", "lo"])
                .output()
                .unwrap();
            if !out.status.success() {
                panic!(
                    "the GigE Vision test needs the loopback addresses 127.0.0.2–4 and could not add {a}: {}\n\
                     run the tests as root (or with CAP_NET_ADMIN), or add them first: \
                     sudo ip addr add {a}/32 dev lo",
                    String::from_utf8_lossy(&out.stderr).trim()
                );
            }
            added.push((*a).to_owned());
        }
        Aliases(added)
    }
}

impl Drop for Aliases {
    fn drop(&mut self) {
        for a in &self.0 {
            let _ = Command::new("ip")
                .args(["addr", "del", &format!("{a}/32"), "dev", "lo"])
                .output();
        }
    }
}

/// A fake GigE Vision camera process, killed on drop.
struct FakeGv(Child);

impl FakeGv {
    fn start(address: &str, serial: &str, lost_per_1000: Option<u32>) -> FakeGv {
        let mut cmd = Command::new(FAKE_GV);
        cmd.args(["-i", address, "-s", serial]);
        if let Some(r) = lost_per_1000 {
            cmd.args(["-r", &r.to_string()]);
        }
        let child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| {
                panic!("cannot start {FAKE_GV} (Debian's aravis-tools, installed by scripts/setup): {e}")
            });
        FakeGv(child)
    }

    fn kill(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Drop for FakeGv {
    fn drop(&mut self) {
        self.kill();
    }
}

struct Rig {
    cameras: Vec<FakeGv>,
    _aliases: Aliases,
}

fn start_rig(lost_per_1000: Option<u32>) -> Rig {
    let aliases = Aliases::ensure();
    let cameras = ADDRESSES
        .iter()
        .enumerate()
        .map(|(i, a)| FakeGv::start(a, &format!("RVGV{i}"), lost_per_1000))
        .collect();
    Rig {
        cameras,
        _aliases: aliases,
    }
}

fn specs() -> Vec<CameraSpec> {
    ADDRESSES
        .iter()
        .enumerate()
        .map(|(i, a)| CameraSpec {
            name: format!("gv{i}"),
            device: DeviceSpec::Id((*a).to_owned()),
        })
        .collect()
}

fn config() -> CaptureConfig {
    CaptureConfig {
        trigger: TriggerMode::Software { rate_hz: 20.0 },
        auto_settle: Duration::from_millis(200),
        reconnect_initial: Duration::from_millis(200),
        reconnect_max: Duration::from_millis(500),
        open_timeout: Duration::from_secs(10),
        ..Default::default()
    }
}

/// The app's processor on the cameras in lock step: each camera under its
/// own gradient law (there is no calibration, so whole frames are metered).
type Loop = LockStep<LiveSource>;

/// Runs capture and control for `duration`; `each` sees every set.
fn run(
    lp: &mut Loop,
    duration: Duration,
    mut each: impl FnMut(&LiveSource, &rigview_core::source::FrameSet),
) {
    let end = Instant::now() + duration;
    while Instant::now() < end {
        if let Some(step) = lp.step().unwrap() {
            each(lp.source(), &step.set);
        }
    }
}

fn open(lost: Option<u32>, config: CaptureConfig) -> (Rig, Loop) {
    let rig = start_rig(lost);
    let t0 = Instant::now();
    let source = LiveSource::open(specs(), config).unwrap();
    println!(
        "four fake GigE Vision cameras open in {:.2} s",
        t0.elapsed().as_secs_f64()
    );
    let cameras = source.cameras().to_vec();
    let settings = ProcessingSettings {
        strategy: Strategy::Single,
        ..Default::default()
    };
    let graph = NeighbourGraph::new(cameras.len(), &[]).unwrap();
    let mut processor = Processor::new(cameras, None, graph, settings).unwrap();
    processor.sync(source.start_settings()).unwrap();
    let mut lp = LockStep::new(source, processor).unwrap();
    lp.set_timeout(Duration::from_millis(200));
    (rig, lp)
}

#[test]
fn software_trigger_at_20_hz_completes_at_least_99_percent_of_sets() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (_rig, mut lp) = open(None, config());
    // Frames of one trigger carry the same frame id on every camera here
    // (each fake camera counts its triggers from the same start).
    let (mut same_ids, mut complete) = (0u64, 0u64);
    run(&mut lp, Duration::from_secs(6), |_, set| {
        if set.is_complete() {
            complete += 1;
            let ids: Vec<u64> = set
                .frames
                .iter()
                .flatten()
                .map(|f| f.meta.frame_id)
                .collect();
            if ids.windows(2).all(|w| w[0] == w[1]) {
                same_ids += 1;
            }
        }
    });
    let st = lp.source().status();
    let total = st.sets.complete + st.sets.incomplete;
    let pct = 100.0 * st.sets.complete as f64 / total.max(1) as f64;
    println!(
        "20 Hz software trigger, 6 s: {} sets, {} complete ({pct:.2} %), {} incomplete; {same_ids} of {complete} complete sets with one frame id throughout; max camera-timestamp skew {:.2} ms (the fake camera polls for triggers every 40 ms)",
        total,
        st.sets.complete,
        st.sets.incomplete,
        st.sets.max_skew_ns as f64 / 1e6
    );
    for c in &st.cameras {
        println!("  {}: {:?}", c.name, c.health);
    }
    assert!(total >= 100, "only {total} sets in 6 s");
    assert!(pct >= 99.0, "{pct:.2} % complete");
    assert_eq!(lp.processed(), st.sets.complete);
}

#[test]
fn with_one_percent_packet_loss_incomplete_frames_are_counted_and_kept_from_the_controller() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    // 8 KiB packets (loopback takes them): 33 packets a frame, so about
    // 72 % of frames and 27 % of sets arrive whole at 1 % loss.
    let config = CaptureConfig {
        packet_size: Some(8192),
        ..config()
    };
    let (_rig, mut lp) = open(Some(10), config);
    let mut incomplete_seen = 0u64;
    run(&mut lp, Duration::from_secs(6), |_, set| {
        if !set.is_complete() {
            incomplete_seen += 1;
        }
    });
    let st = lp.source().status();
    let h = lp.source().health();
    let missing: u64 = h.iter().map(|h| h.missing_packets).sum();
    let resent: u64 = h.iter().map(|h| h.resent_packets).sum();
    let failed: u64 = h.iter().map(|h| h.failed).sum();
    println!(
        "-r 10: {} sets, {} complete, {} incomplete ({} broken frames, {} missing); buffers failed {failed}; packets missing {missing}, resent {resent}; controller fed {}, kept {}",
        st.sets.complete + st.sets.incomplete,
        st.sets.complete,
        st.sets.incomplete,
        st.sets.broken_frames,
        st.sets.missing_frames,
        lp.processed(),
        lp.incomplete()
    );
    assert!(st.sets.complete + st.sets.incomplete >= 60);
    assert!(st.sets.incomplete > 0 && st.sets.broken_frames > 0);
    assert!(lp.processed() > 0, "no set arrived whole");
    assert!(h.iter().all(|h| h.state == StreamState::Streaming), "{h:?}");
    // The controller saw exactly the complete sets.
    assert_eq!(lp.processed(), st.sets.complete);
    assert_eq!(lp.incomplete(), incomplete_seen);
    assert_eq!(st.sets.incomplete, incomplete_seen);
}

#[test]
fn a_killed_camera_is_lost_while_the_others_go_on_and_rejoins_after_a_restart() {
    // The source reports losses and rejoins as events of the thread that
    // drives it: this one.
    let log = LogBuffer::new();
    let _events = rigview::logging::capture(&log);
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (mut rig, mut lp) = open(None, config());
    run(&mut lp, Duration::from_secs(2), |_, _| {});
    let before = lp.source().status().sets.clone();

    // Kill camera 3.
    rig.cameras[3].kill();
    let killed = Instant::now();
    let mut lost_after = None;
    let mut three_camera_sets = 0u64;
    run(&mut lp, Duration::from_secs(4), |s, set| {
        let others = set.frames[..3]
            .iter()
            .all(|f| f.as_ref().is_some_and(|f| f.is_complete()));
        if others && set.frames[3].is_none() {
            three_camera_sets += 1;
        }
        if lost_after.is_none() && s.health()[3].state != StreamState::Streaming {
            lost_after = Some(killed.elapsed());
        }
    });
    let lost_after = lost_after.expect("the killed camera was never marked lost");
    let health = lp.source().health();
    println!(
        "killed gv3: marked {:?} after {:.2} s; {three_camera_sets} sets from the other three in the next 4 s",
        health[3].state,
        lost_after.as_secs_f64()
    );
    assert_ne!(health[3].state, StreamState::Streaming);
    assert!(health[..3]
        .iter()
        .all(|h| h.state == StreamState::Streaming));
    assert!(
        three_camera_sets >= 40,
        "only {three_camera_sets} sets from the other three"
    );

    // Restart it.
    rig.cameras[3] = FakeGv::start(ADDRESSES[3], "RVGV3", None);
    let restarted = Instant::now();
    let mut rejoined = None;
    run(&mut lp, Duration::from_secs(5), |s, set| {
        if rejoined.is_none() && s.health()[3].state == StreamState::Streaming && set.is_complete()
        {
            rejoined = Some(restarted.elapsed());
        }
    });
    let st = lp.source().status();
    let lines: Vec<String> = log.since(0).iter().map(|e| e.line()).collect();
    for l in &lines {
        println!("  {l}");
    }
    // The loss is a warning naming the camera, the rejoin a note.
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("warning: gv3: ") && l.ends_with("(stream lost)")),
        "{lines:?}"
    );
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("gv3: streaming: rejoined")),
        "{lines:?}"
    );
    let rejoined = rejoined.expect("camera 3 did not rejoin within 5 s");
    println!(
        "restarted gv3: rejoined (first complete set) after {:.2} s; sets before kill {} complete, at the end {} complete / {} incomplete",
        rejoined.as_secs_f64(),
        before.complete,
        st.sets.complete,
        st.sets.incomplete
    );
    assert!(
        rejoined <= Duration::from_secs(3),
        "rejoined after {rejoined:?}"
    );
    assert_eq!(st.cameras[3].rejoins, 1);
}
