#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The simulator's asset files match what is built in: the reference rig
//! (`assets/reference.rig.yaml`, bit for bit) and every simulation preset
//! written out in full (`assets/sim/<preset>.sim.yaml`). Set
//! `RIGVIEW_REGENERATE_ASSETS=1` to write them anew after changing a
//! preset.

use std::path::PathBuf;

use rigview_calib::formats::{self, rig_yaml};
use rigview_core::sim::{reference_rig, SimConfig, SimRender, PRESETS};

fn assets() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets")
}

fn regenerate() -> bool {
    std::env::var_os("RIGVIEW_REGENERATE_ASSETS").is_some()
}

#[test]
fn the_reference_rig_file_is_the_built_in_rig() {
    let path = assets().join("reference.rig.yaml");
    let rig = reference_rig().unwrap();
    if regenerate() {
        let text = rig_yaml::to_string(&rig).unwrap();
        std::fs::write(
            &path,
            format!(
                "# The simulated reference rig: four 185° Kannala–Brandt fisheye cameras at\n\
                 # 1288×964 on a 4.6 m × 1.8 m car, about 1 m up and tilted down (front 20°,\n\
                 # back 30°, mirrors 45°). Written by rigview from core/src/sim/rig.rs; the\n\
                 # simulator renders with exactly this calibration.\n{text}"
            ),
        )
        .unwrap();
    }
    let loaded = formats::load(&path, None, None).unwrap().rig;
    assert_eq!(
        loaded,
        rig,
        "{} differs from the built-in rig: regenerate it",
        path.display()
    );
}

#[test]
fn every_preset_is_written_out_in_full() {
    for (name, ..) in PRESETS {
        let path = assets().join("sim").join(format!("{name}.sim.yaml"));
        let preset = SimConfig::preset(name).unwrap();
        if regenerate() {
            std::fs::write(&path, preset.to_yaml().unwrap()).unwrap();
        }
        let loaded = SimConfig::load(&path).unwrap();
        let expected = SimConfig {
            name: path.display().to_string(),
            ..preset
        };
        assert_eq!(
            loaded,
            expected,
            "{} differs from the preset: regenerate it",
            path.display()
        );
    }
}

#[test]
fn a_simulation_file_can_name_a_rig_file() {
    let dir = std::env::temp_dir().join(format!("rigview-sim-assets-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("custom.sim.yaml");
    let rig = assets().join("reference.rig.yaml");
    std::fs::write(
        &file,
        format!(
            "format: rigview-sim\nversion: 1\nrig: {}\nscale: 0.125\nsupersample: 1\nscript: steps\n",
            rig.display()
        ),
    )
    .unwrap();
    let config = SimConfig::load(&file).unwrap();
    let render = SimRender::new(&config).unwrap();
    assert_eq!(render.cameras().len(), 4);
    assert_eq!(
        (render.cameras()[0].width, render.cameras()[0].height),
        (161, 121)
    );
    // A rig file that is not there, or one without poses, is refused with
    // its name.
    std::fs::write(
        &file,
        "format: rigview-sim\nversion: 1\nrig: nowhere.rig.yaml\n",
    )
    .unwrap();
    let err = SimRender::new(&SimConfig::load(&file).unwrap())
        .unwrap_err()
        .to_string();
    assert!(err.contains("nowhere.rig.yaml"), "{err}");
    let camchain = assets().join("surround-nz.camchain.yaml");
    std::fs::write(
        &file,
        format!(
            "format: rigview-sim\nversion: 1\nrig: {}\n",
            camchain.display()
        ),
    )
    .unwrap();
    let err = SimRender::new(&SimConfig::load(&file).unwrap())
        .unwrap_err()
        .to_string();
    assert!(err.contains("vehicle frame"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Every simulation file in `assets/sim` loads and renders (at an eighth
/// of its resolution), the real scenes with their panoramas; and each real
/// scene's ground is lit by its map (no pixel of a camera's ground black).
#[test]
fn every_simulation_file_in_the_assets_renders() {
    let mut real = 0;
    let mut files: Vec<_> = std::fs::read_dir(assets().join("sim"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".sim.yaml"))
        .collect();
    files.sort();
    assert!(files.len() >= 16, "{files:?}");
    for path in files {
        let config = SimConfig {
            scale: 0.125,
            supersample: 1,
            ..SimConfig::load(&path).unwrap()
        };
        let render = SimRender::new(&config).unwrap();
        if config.scene.environment.is_some() {
            real += 1;
            let info = &render.cameras()[0];
            let light = render.irradiance(0, 0.0).unwrap();
            let ground: Vec<f32> = (0..info.height)
                .flat_map(|y| (0..info.width).map(move |x| (x, y)))
                .filter(|&(x, y)| render.class(0, x, y) == Some(rigview_core::sim::Class::Ground))
                .map(|(x, y)| light[y * info.width + x])
                .collect();
            assert!(!ground.is_empty(), "{}", path.display());
            assert!(
                ground.iter().all(|v| *v > 0.0),
                "{}: a ground pixel is black",
                path.display()
            );
        }
    }
    assert_eq!(real, 5, "the real scenes");
}
