//! A recording as a frame source: exactly the recorded sets, in order; a
//! paced replay holds a set back until it is due without losing it; an
//! indexed file seeks to any set, a killed one replays without seeking.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::fs::File;
use std::io::BufWriter;
use std::time::Duration;

use common::Sim;
use rigview_core::image::PixelFormat;
use rigview_core::source::FrameSource;
use rigview_record::{Compression, ReplaySource, SetWriter};

#[test]
fn a_replay_gives_the_recorded_sets_and_a_paced_one_holds_them_back() {
    let sim = Sim::new(PixelFormat::Mono8, 0.25);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.mcap");
    let sets: Vec<_> = (0..4).map(|k| sim.set(9, k)).collect();
    {
        let out = BufWriter::new(File::create(&path).unwrap());
        let mut w = SetWriter::new(&path, out, &sim.setup(), Compression::None).unwrap();
        for s in &sets {
            w.write_set(s, sim.telemetry(s), 0, 1).unwrap();
        }
        w.finish("finished").unwrap();
    }
    let mut replay = ReplaySource::open(&path).unwrap();
    assert_eq!(replay.cameras(), &sim.cameras[..]);
    assert!(replay.meta().rig_yaml.is_some());
    let t = Duration::ZERO;
    // A speed so slow that the second set is due in years: it is held back.
    replay.set_speed(Some(1e-12));
    assert_eq!(replay.next_set(t).unwrap().unwrap().trigger, 0);
    assert!(replay.next_set(t).unwrap().is_none());
    assert!(replay.next_set(t).unwrap().is_none());
    assert!(!replay.is_finished());
    replay.set_speed(None);
    for want in &sets[1..] {
        let got = replay.next_set(t).unwrap().unwrap();
        assert_eq!(got.trigger, want.trigger);
        assert_eq!(got.timestamp_ns, want.timestamp_ns);
        for (a, b) in got.frames.iter().zip(&want.frames) {
            let (a, b) = (a.as_ref().unwrap(), b.as_ref().unwrap());
            assert_eq!(a.meta, b.meta);
            assert!(a.data[..] == b.data[..]);
        }
    }
    assert!(replay.next_set(t).unwrap().is_none());
    assert!(replay.is_finished());
    assert!(
        replay.take_messages().is_empty(),
        "a closed file ends quietly"
    );

    // Seeking: to set 2, one back, past the end, to the start.
    assert_eq!(replay.times().unwrap().len(), 4);
    replay.seek(2).unwrap();
    assert!(!replay.is_finished());
    assert_eq!(replay.position(), Some(2));
    assert_eq!(replay.next_set(t).unwrap().unwrap().trigger, 2);
    replay.seek(replay.position().unwrap() - 2).unwrap();
    assert_eq!(replay.next_set(t).unwrap().unwrap().trigger, 1);
    replay.seek(9).unwrap();
    assert!(replay.is_finished());
    assert!(replay.next_set(t).unwrap().is_none());
    replay.seek(0).unwrap();
    let again = replay.next_set(t).unwrap().unwrap();
    assert_eq!(again.trigger, 0);
    assert!(
        again.frames[0].as_ref().unwrap().data[..] == sets[0].frames[0].as_ref().unwrap().data[..]
    );

    // A killed file (cut in its last set) replays from start to end and
    // cannot seek.
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 9 / 10]).unwrap();
    let mut killed = ReplaySource::open(&cut).unwrap();
    assert!(killed.times().is_none());
    let e = killed.seek(1).unwrap_err().to_string();
    assert!(e.contains("repair"), "{e}");
    let mut n = 0;
    while let Some(s) = killed.next_set(t).unwrap() {
        assert_eq!(s.trigger, n);
        n += 1;
    }
    assert_eq!(n, 3, "the cut set is left out");
    let notes = killed.take_messages();
    assert!(notes.iter().any(|m| m.contains("ends early")), "{notes:?}");
}
