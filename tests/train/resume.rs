//! Stopping and continuing a run: SIGINT, bit-for-bit resumes with every option, and
//! the checkpoints, masks and rows a resume refuses or repairs.

use super::*;

#[test]
fn sigint_stops_everything_and_resume_continues_the_rows() {
    let dir = TempDir::fresh("sigint");
    let d = dir.to_str().unwrap();
    // 1 actor: 128 steps an update; 2000 updates (seconds: long enough to interrupt).
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "1",
                "--steps",
                "256000",
                "--checkpoint-every",
                "100000",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 4, Duration::from_secs(60));
    let pid = c.id();
    signal(pid, "-INT");
    let t0 = Instant::now();
    let (status, err, _) = finish(c, Duration::from_secs(30));
    assert!(
        t0.elapsed() < Duration::from_secs(5),
        "stopped in {:?}",
        t0.elapsed()
    );
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(err.contains("--resume"), "{err}");
    assert_nothing_left(&namespace_of(&err));
    // The final checkpoint holds the last finished update (no periodic one was due).
    let before = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert!(!before.is_empty() && (before.len() as u64) < 2000);
    assert!(dir.join("checkpoints/latest.safetensors").exists());

    let c = train(&["--resume", d]);
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    assert!(err.contains("resuming"), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 2000, 128);
    // Rows written before the stop are kept as they were.
    for (a, b) in before.iter().zip(&rows) {
        assert_eq!(a.csv(), b.csv());
    }
    // Wall time continues across the resume.
    assert!(rows.last().unwrap().wall_s > before.last().unwrap().wall_s);
}

#[test]
fn a_resumed_run_equals_an_uninterrupted_one_bit_for_bit() {
    resumed_equals_uninterrupted("exact", &[]);
}

/// The new forms carry state across chunks (first-visit's paid flags, the potential of
/// each world's state), the unmasked policy samples other actions, and a cropped view
/// changes the network's input: each resumes to the same bits as a run that never
/// stopped.
#[test]
fn resumes_are_bit_for_bit_with_every_new_option() {
    for (tag, extra) in [
        ("exact-fv", &["--intrinsic", "first-visit"][..]),
        ("exact-hp", &["--intrinsic", "horizon-potential"][..]),
        ("exact-nomask", &["--no-action-mask"][..]),
        // The KL coefficient adapts after each update and is checkpointed.
        ("exact-rllib", &["--ppo-preset", "rllib"][..]),
        // Two value heads: the intrinsic rewards' running scale is checkpointed.
        ("exact-2h", &["--intrinsic-value-head", "--beta", "0.1"][..]),
        // A partial view: the network takes the 5 x 5 window around the agent; and
        // periodic evaluations, which the resumed run makes again after its checkpoint.
        ("exact-crop", &["--view", "crop:2", "--eval-every", "2"][..]),
    ] {
        resumed_equals_uninterrupted(tag, extra);
    }
}

fn resumed_equals_uninterrupted(tag: &str, extra: &[&str]) {
    resumed_equals_uninterrupted_on("room", tag, extra);
}

#[test]
fn a_damaged_checkpoint_is_refused_on_resume_before_anything_starts() {
    let dir = TempDir::fresh("damaged");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "512", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, _) = finish(c, Duration::from_secs(60));
    assert!(status.success(), "{err}");
    let ckpt = dir.join("checkpoints/latest.safetensors");
    let good = std::fs::read(&ckpt).unwrap();
    let config = std::fs::read(dir.join("config.toml")).unwrap();
    let rows = std::fs::read(dir.join("metrics.csv")).unwrap();
    // Truncated, then one flipped byte in the tensor data (the checksum catches it).
    let mut flipped = good.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 0x40;
    for (bytes, says) in [
        (good[..good.len() / 2].to_vec(), "truncated or corrupt"),
        (flipped, "checksum"),
    ] {
        std::fs::write(&ckpt, &bytes).unwrap();
        let (status, err, _) = finish(
            train(&["--resume", d, "--steps", "1024"]),
            Duration::from_secs(30),
        );
        assert_eq!(status.code(), Some(2), "{err}");
        assert!(
            err.contains(&ckpt.display().to_string()),
            "names the file: {err}"
        );
        assert!(err.contains(says), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
        assert!(!err.contains("namespace"), "no process started: {err}");
        // Nothing of the run was touched.
        assert_eq!(std::fs::read(dir.join("config.toml")).unwrap(), config);
        assert_eq!(std::fs::read(dir.join("metrics.csv")).unwrap(), rows);
    }
}

/// The action mask is recorded in the checkpoint: a config.toml edited to the other
/// setting is refused on --resume before anything starts (exit 2, one sentence); so
/// are flags that would change the policy's settings (the view, the seed).
#[test]
fn a_checkpoint_is_never_continued_with_the_other_action_mask() {
    let dir = TempDir::fresh("mask-flip");
    let d = dir.to_str().unwrap();
    let (s, err, _) = finish(
        train(
            &[
                &["room", "--actors", "1", "--steps", "256", "--out", d][..],
                SMALL,
            ]
            .concat(),
        ),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    // Flags that would change what the policy learns are refused on --resume, named.
    let (s, err, _) = finish(
        train(&["--resume", d, "--view", "crop:2", "--seed", "3"]),
        Duration::from_secs(60),
    );
    assert_eq!(s.code(), Some(2), "{err}");
    assert!(
        err.contains("--view, --seed cannot be changed (start a new run instead)"),
        "{err}"
    );
    let (s, err, _) = finish(train(&["--resume", d, "--paper"]), Duration::from_secs(60));
    assert_eq!(s.code(), Some(2), "{err}");
    assert!(
        err.contains("--paper cannot be changed (start a new run instead)"),
        "{err}"
    );
    let cfg = dir.join("config.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    assert!(text.contains("action_mask = true"), "{text}");
    assert!(text.contains("view = \"full\""), "{text}");
    std::fs::write(
        &cfg,
        text.replace("action_mask = true", "action_mask = false"),
    )
    .unwrap();
    let (s, err, _) = finish(
        train(&["--resume", d, "--steps", "512"]),
        Duration::from_secs(60),
    );
    assert_eq!(s.code(), Some(2), "{err}");
    assert!(err.contains("trained with action_mask = true"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}

#[test]
fn a_torn_metrics_row_is_dropped_on_resume() {
    let dir = TempDir::fresh("torn");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "1024", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, _) = finish(c, Duration::from_secs(60));
    assert!(status.success(), "{err}");
    // A crash in the middle of writing row 9.
    let path = dir.join("metrics.csv");
    let mut text = std::fs::read_to_string(&path).unwrap();
    text.push_str("9,1152,4,0.");
    std::fs::write(&path, text).unwrap();
    let (status, err, _) = finish(
        train(&["--resume", d, "--steps", "2048"]),
        Duration::from_secs(60),
    );
    assert!(status.success(), "{err}");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.lines().skip(1).all(|l| MetricsRow::parse(l).is_some()),
        "{text}"
    );
    assert_contiguous(&read_metrics(&path).unwrap(), 16, 128);
}

/// A run whose tool is `auto` records the tool the selection gave at its start, and a
/// resume keeps it whatever the selection gives then (here the record is made to
/// disagree by hand: exp2 selects the wand for boulder+door).
#[test]
fn a_resume_keeps_the_tool_the_run_selected_when_it_started() {
    let dir = TempDir::fresh("selected");
    let d = dir.to_str().unwrap();
    let (s, err, _) = finish(
        train(&[&["exp2", "--steps", "256", "--out", d][..], SMALL].concat()),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    assert!(
        err.contains("tool selection for conditions:boulder+door: wand"),
        "{err}"
    );
    let path = dir.join("config.toml");
    let cfg = std::fs::read_to_string(&path).unwrap();
    assert!(
        cfg.contains("\ntool = \"default\"\nselected_tool = \"wand\"\n"),
        "{cfg}"
    );
    std::fs::write(
        &path,
        cfg.replace("selected_tool = \"wand\"", "selected_tool = \"axe\""),
    )
    .unwrap();
    let (s, err, _) = finish(
        train(&["--resume", d, "--steps", "512"]),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    assert!(
        err.contains(
            "the run selected axe when it started; the selection gives wand now: keeping axe"
        ),
        "{err}"
    );
    // A tool the world does not have: one sentence, exit 2, nothing started.
    let cfg = std::fs::read_to_string(&path).unwrap();
    std::fs::write(
        &path,
        cfg.replace("selected_tool = \"axe\"", "selected_tool = \"spoon\""),
    )
    .unwrap();
    let (s, err, _) = finish(
        train(&["--resume", d, "--steps", "768"]),
        Duration::from_secs(120),
    );
    assert_eq!(s.code(), Some(2), "{err}");
    assert!(err.contains("records the selected tool 'spoon'"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
