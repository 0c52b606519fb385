//! What a run trains with: asynchronous actors, every intrinsic form, one horizon
//! everywhere, recorded episodes.

use super::*;

#[test]
fn asynchronous_actors_record_their_policy_lag() {
    let dir = TempDir::fresh("async");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "25600",
                "--max-policy-lag",
                "3",
                "--no-empowerment",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 100, 256);
    assert!(rows.iter().all(|r| (0.0..=3.0).contains(&r.policy_lag)));
    // Actors ran ahead of the learner: some chunks came from an older policy.
    assert!(rows.iter().any(|r| r.policy_lag > 0.0), "no lag recorded");
}

#[test]
fn every_intrinsic_form_trains_with_two_actors_and_logs_its_diagnostics() {
    for form in [
        "potential",
        "count",
        "none",
        "horizon-potential",
        "first-visit",
    ] {
        let dir = TempDir::fresh(form);
        let d = dir.to_str().unwrap();
        let c = train(
            &[
                &["room", "--actors", "2", "--steps", "4096", "--out", d][..],
                &["--intrinsic", form],
                SMALL,
            ]
            .concat(),
        );
        let (status, err, _) = finish(c, Duration::from_secs(120));
        assert!(status.success(), "{form}: {err}");
        let cfg = std::fs::read_to_string(dir.join("config.toml")).unwrap();
        assert!(cfg.contains(&format!("intrinsic = \"{form}\"")), "{cfg}");
        let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
        assert_contiguous(&rows, 16, 256);
        for r in &rows {
            match form {
                // gamma E' - E lies in [-max E, max E]; the room's E is at most a few bits.
                "potential" => {
                    assert!(r.intrinsic_mean.abs() < 4.0, "{r:?}");
                    assert!((0.0..=1.0).contains(&r.e_positive_frac), "{r:?}");
                }
                // gamma Phi' - Phi, Phi the sum of E^h over h <= 8 (a few bits each).
                "horizon-potential" => {
                    assert!(r.intrinsic_mean.abs() < 32.0, "{r:?}");
                }
                // E paid at most once per inventory per episode: far under E per step.
                "first-visit" => {
                    assert!(r.intrinsic_mean >= 0.0 && r.intrinsic_mean < 0.5, "{r:?}");
                    // NaN when no episode ended in the update.
                    assert!(
                        r.intrinsic_return.is_nan() || r.intrinsic_return >= 0.0,
                        "{r:?}"
                    );
                }
                // 1 / sqrt(N) with N >= 1, and N grows: the mean is in (0, 1].
                "count" => {
                    assert!(r.intrinsic_mean > 0.0 && r.intrinsic_mean <= 1.0, "{r:?}");
                    assert!(r.e_positive_frac.is_nan(), "{r:?}");
                }
                _ => assert_eq!(r.intrinsic_mean, 0.0),
            }
        }
        if form == "count" {
            // States are revisited by both actors: the mean bonus falls.
            assert!(rows.last().unwrap().intrinsic_mean < rows[0].intrinsic_mean);
        }
        // The room's axe is next to the agent: picked up in the first updates.
        let first = rows.iter().find_map(|r| r.first_pickup_step).unwrap();
        assert!(first <= 4096 && first % 256 == 0, "{first}");
        assert!(rows
            .iter()
            .all(|r| r.first_pickup_step.is_none_or(|s| s == first)));
        assert_nothing_left(&namespace_of(&err));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn one_horizon_everywhere_with_horizon_mode_fixed_and_recorded_episodes() {
    let dir = TempDir::fresh("fixed");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--steps", "1024", "--out", d][..],
            &["--horizon-mode", "fixed", "--horizon-unequipped", "5"],
            &["--record", "2"],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, out) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    // --record 2: two strips of the final policy's episodes.
    assert!(out.contains("2 episodes of the final policy"), "{out}");
    for k in 1..=2 {
        let png = std::fs::read(dir.join(format!("episodes/episode-{k}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    }
    assert!(!dir.join("episodes/episode-3.png").exists());

    // `record --gif`: the same episodes as animations, one frame per state (the start
    // and one after each step), every frame the size of the first.
    let gifs = dir.join("gifs");
    let out = crate::util::fulcrum()
        .args(["record", d, "--episodes", "2", "--gif", "--seed", "5"])
        .arg("--out")
        .arg(&gifs)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4, "{text}");
    for k in 1..=2 {
        let line = lines
            .iter()
            .find(|l| l.contains(&format!("episode-{k}.gif")))
            .unwrap_or_else(|| panic!("no episode-{k}.gif in {text}"));
        let steps: usize = line
            .split('(')
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no step count in {line}"));
        assert!((1..=50).contains(&steps), "{line}");
        let file = std::fs::File::open(gifs.join(format!("episode-{k}.gif"))).unwrap();
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut dec = opts.read_info(file).unwrap();
        // room is 7 x 5 cells of 14 pixels; the frame adds 8 pixels each side (at least
        // 160 wide), and 22 + 16 + 8 pixels of heading, caption and margin.
        assert_eq!((dec.width(), dec.height()), (160, 22 + 5 * 14 + 16 + 8));
        let mut frames = 0;
        while let Some(f) = dec.read_next_frame().unwrap() {
            assert_eq!((f.width, f.height), (160, 116));
            assert_eq!(f.delay, 25);
            frames += 1;
        }
        assert_eq!(frames, steps + 1, "{line}");
    }
    let cfg = std::fs::read_to_string(dir.join("config.toml")).unwrap();
    assert!(cfg.contains("horizon_unequipped = 5\n"), "{cfg}");
    assert!(cfg.contains("horizon_equipped = 5\n"), "{cfg}");
    assert!(cfg.contains("horizon_mode = \"fixed\""), "{cfg}");
}

#[test]
fn the_potential_counts_a_destroy_tasks_boulder_by_its_condition() {
    // A room whose task is to destroy a boulder the agent can also push about.
    let w = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/worlds/boulder-room.toml"
    );
    let root = TempDir::fresh("conditions");
    let run = |tag: &str, extra: &[&str]| {
        let dir = root.join(tag);
        let d = dir.to_str().unwrap();
        let c = train(&[&[w, "--steps", "256", "--out", d][..], extra, SMALL].concat());
        let (status, err, _) = finish(c, Duration::from_secs(120));
        assert!(status.success(), "{tag}: {err}");
        let cfg = std::fs::read_to_string(dir.join("config.toml")).unwrap();
        (cfg, err)
    };
    // The default: the boulder by its condition. Phi = max(0, H + 1 - d(s)) with H = 6,
    // and d = 1 in the state that faces it with the pickaxe chosen, so max Phi = 6 and
    // beta = 0.4 / 6.
    let (cfg, err) = run("default", &[]);
    assert!(cfg.contains("potential_objects = \"task\"\n"), "{cfg}");
    assert!(cfg.contains(&format!("beta = {}\n", 0.4 / 6.0)), "{cfg}");
    assert!(
        err.contains("tool selection for conditions:boulder: pickaxe"),
        "{err}"
    );
    // The full state: the boulder's cells count, Phi exceeds H somewhere, beta is smaller.
    let (cfg, err) = run("full", &["--potential-objects", "full"]);
    assert!(cfg.contains("potential_objects = \"full\"\n"), "{cfg}");
    assert!(err.contains("tool selection for boulder: pickaxe"), "{err}");
    let beta = beta_of(&cfg);
    assert!(beta < 0.4 / 6.0, "{beta}");
    // The additive bonus is E itself: the full state.
    let (_, err) = run("additive", &["--intrinsic", "additive"]);
    assert!(err.contains("tool selection for boulder: pickaxe"), "{err}");
    let _ = std::fs::remove_dir_all(&root);
}
