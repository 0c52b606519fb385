//! Poisoned inputs in a live run: a chunk that looks right (run tag, world hash, shape)
//! but carries a glyph or an episode record no actor could have written, sent into the
//! run's own trajectory service; and a checkpoint whose episode records are not states
//! of the world, resumed.

use std::time::{Duration, Instant};

use fulcrum_contracts::checkpoint;
use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::traj::{
    self, ChunkHeader, ChunkLayout, EnvRecord, Section, TrainNames, ENV_BYTES,
};
use fulcrum_contracts::valid::check_record;
use fulcrum_learner::metrics::read_metrics;
use fulcrum_world::World;
use iceoryx2::prelude::*;

use super::{assert_contiguous, finish, train, wait_rows, SMALL};
use crate::util::{pids_with, signal, wait_until, TempDir};

/// The namespace of the learner running for the run directory `d`.
fn learner_namespace(d: &str) -> String {
    let t0 = Instant::now();
    loop {
        if let Some(&p) = pids_with(&["__learner", d]).first() {
            let cmd = std::fs::read(format!("/proc/{p}/cmdline")).unwrap();
            let args: Vec<String> = String::from_utf8_lossy(&cmd)
                .split('\0')
                .map(str::to_string)
                .collect();
            let i = args.iter().position(|a| a == "--namespace").unwrap();
            return args[i + 1].clone();
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "no learner");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A chunk of `w` that an actor could have written: 4 worlds x 32 steps standing at the
/// initial state (action N into the wall), their observations and records, zero
/// rewards and values, log-probabilities 0.
fn plausible_chunk(w: &World, ns: &str, layout: &ChunkLayout) -> (ChunkHeader, Vec<u8>) {
    let h = ChunkHeader {
        run: traj::run_tag(ns),
        world_hash: w.content_hash(),
        // An actor id no actor of this run has.
        actor: 7,
        envs: layout.envs as u32,
        steps: layout.steps as u32,
        cells: layout.cells as u32,
        flags: layout.flags as u32,
        actions: w.num_actions() as u32,
        len: layout.bytes() as u64,
        ..ChunkHeader::default()
    };
    let mut p = vec![0u8; layout.bytes()];
    let (c, f) = (layout.cells, layout.flags);
    let (g0, f0) = (
        layout.range(Section::Glyphs).start,
        layout.range(Section::Flags).start,
    );
    for i in 0..layout.n() {
        let mut flags = vec![0u8; f];
        w.observe(&w.initial, &mut p[g0 + i * c..g0 + (i + 1) * c], &mut flags);
        p[f0 + i * f..f0 + (i + 1) * f].copy_from_slice(&flags);
    }
    let er = layout.range(Section::EnvState).start;
    for e in 0..layout.envs {
        p[er + e * ENV_BYTES..er + (e + 1) * ENV_BYTES]
            .copy_from_slice(&EnvRecord::new(w.reset()).to_bytes());
    }
    (h, p)
}

#[test]
fn poisoned_chunks_are_refused_and_counted_while_the_run_goes_on() {
    fulcrum_empowerment::service::quiet_ipc_logs();
    let dir = TempDir::fresh("poison-chunk");
    let d = dir.to_str().unwrap();
    // Asynchronous PPO with a lag no run reaches: a chunk of policy version 0 is fresh
    // enough to be trained on whenever it comes, so a bad one that passed the check would
    // reach the update. The run is far longer than the test: it is stopped with SIGINT
    // once the chunks have been judged, so how fast this machine trains does not matter.
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "25600000", "--out", d][..],
            &["--no-empowerment", "--max-policy-lag", "1000000000"],
            &["--checkpoint-every", "1000000"],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    let ns = learner_namespace(d);
    let w = fulcrum_world::load_world("room").unwrap();
    let spec = w.obs_spec();
    let layout = ChunkLayout {
        envs: 4,
        steps: 32,
        cells: spec.cells(),
        flags: spec.flags,
    };
    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .unwrap();
    let svc = traj::trajectory_service(&node, &TrainNames::new(&ns)).unwrap();
    let publisher = svc
        .publisher_builder()
        .initial_max_slice_len(layout.bytes())
        .create()
        .unwrap();
    let (h, clean) = plausible_chunk(&w, &ns, &layout);
    // One glyph byte beyond room's 10 glyphs; one world record with the agent in the
    // rock of the map's corner; and the clean chunk, which the check lets through.
    let mut bad_glyph = clean.clone();
    bad_glyph[layout.range(Section::Glyphs).start + 9] = 200;
    let mut bad_record = clean.clone();
    let er = layout.range(Section::EnvState).start + 2 * ENV_BYTES;
    bad_record[er] = 0;
    bad_record[er + 1] = 0;
    assert!(check_record(&w, &bad_record[er..er + ENV_BYTES]).is_err());
    for (seq, payload) in [bad_glyph, bad_record, clean].into_iter().enumerate() {
        let mut s = publisher.loan_slice(layout.bytes()).unwrap();
        s.payload_mut().copy_from_slice(&payload);
        *s.user_header_mut() = ChunkHeader {
            seq: seq as u64,
            ..h
        };
        // Delivered to the learner's subscriber (the run is still going).
        assert_eq!(s.send().unwrap(), 1);
    }
    // The learner takes the chunks in order: once it has refused two, the clean one
    // (sent last) has been judged too; a hundred more updates and the run is stopped.
    let mut judged = None;
    wait_until(Duration::from_secs(60), "two refused chunks", || {
        let rows = read_metrics(&dir.join("metrics.csv")).unwrap_or_default();
        if judged.is_none() {
            judged = rows
                .iter()
                .find(|r| r.dropped_chunks >= 2)
                .map(|r| r.update);
        }
        judged.is_some_and(|u| rows.last().is_some_and(|r| r.update >= u + 100))
    });
    signal(c.id(), "-INT");
    let (status, err, _) = finish(c, Duration::from_secs(60));
    assert_eq!(status.code(), Some(130), "{err}");
    let err = without_colours(&err);
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, rows.len() as u64, 128);
    assert_eq!(
        rows.last().unwrap().dropped_chunks,
        2,
        "the two poisoned chunks refused, the clean one used: {err}"
    );
    for says in [
        "glyph 200 at cell 9 is not one of the world's 10 glyphs",
        "world 2's episode record: its state is not one of the world's: the agent cannot stand at 0,0: that cell is rock",
    ] {
        assert!(err.contains(says), "the log names the reason ({says}): {err}");
    }
    // What the checkpoint stored of the worlds are states of the world.
    assert_stored_records_valid(&dir, &w);
}

/// `text` without its terminal colour sequences (`ESC [ ... m`), as a log reader sees it.
fn without_colours(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut it = text.chars();
    while let Some(ch) = it.next() {
        if ch == '\u{1b}' {
            for c in it.by_ref() {
                if c == 'm' {
                    break;
                }
            }
        } else {
            out.push(ch);
        }
    }
    out
}

/// Every episode record of the run's checkpoint is one of the world's.
fn assert_stored_records_valid(dir: &std::path::Path, w: &World) {
    let cfg = RunConfig::load(&dir.join("config.toml")).unwrap();
    let ck = checkpoint::read(
        &dir.join("checkpoints/latest.safetensors"),
        &cfg.shape(w).params(),
    )
    .unwrap();
    let envs: Vec<_> = ck
        .extra
        .blobs
        .iter()
        .filter(|(k, _)| k.starts_with("env/"))
        .collect();
    assert!(!envs.is_empty());
    for (k, b) in envs {
        for r in b.chunks(ENV_BYTES) {
            assert!(check_record(w, r).is_ok(), "{k}: {:?}", check_record(w, r));
        }
    }
}

#[test]
fn a_checkpoint_with_invalid_world_records_resumes_with_fresh_episodes() {
    let dir = TempDir::fresh("poison-ckpt");
    let d = dir.to_str().unwrap();
    // With the empowerment service, which knows room's state space.
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "1280", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let w = fulcrum_world::load_world("room").unwrap();
    let cfg = RunConfig::load(&dir.join("config.toml")).unwrap();
    let path = dir.join("checkpoints/latest.safetensors");
    let params = cfg.shape(&w).params();
    let mut ck = checkpoint::read(&path, &params).unwrap();
    let blob = ck.extra.blobs.get_mut("env/0").expect("actor 0's worlds");
    assert_eq!(blob.len(), 4 * ENV_BYTES);
    // World 0: the agent in the rock of the corner; world 1: mode 200 (room has one
    // tool: modes 0..=2); world 2: the tree felled without the axe, a state that
    // passes every local check but is not reachable (only the service knows);
    // world 3 untouched.
    blob[0] = 0;
    blob[1] = 0;
    blob[ENV_BYTES + 2] = 200;
    let s2 = 2 * ENV_BYTES;
    blob[s2..s2 + 38].copy_from_slice(&{
        let mut s = w.initial;
        s.objects[0] = 2;
        s.to_bytes()
    });
    // Only the first two fail the local check.
    let bad: Vec<bool> = blob
        .chunks(ENV_BYTES)
        .map(|r| check_record(&w, r).is_err())
        .collect();
    assert_eq!(bad, [true, true, false, false]);
    // The writer recomputes the checksum: the file is whole, only its records are bad.
    checkpoint::write(&path, &ck.params, ck.step, &ck.extra).unwrap();
    assert!(checkpoint::read(&path, &params).is_ok());

    let c = train(&["--resume", d, "--steps", "2560"]);
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let err = without_colours(&err);
    let warnings: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("is not a valid state: that world starts a new episode"))
        .collect();
    assert_eq!(warnings.len(), 3, "one warning per bad world: {err}");
    for (e, why) in [
        (0, "that cell is rock"),
        (1, "mode 200"),
        (2, "not in the world's state space"),
    ] {
        assert!(
            warnings
                .iter()
                .any(|l| l.contains(&format!("world={e}")) && l.contains(why)),
            "world {e}: {why}: {err}"
        );
    }
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 20, 128);
    assert_eq!(rows.last().unwrap().actor_restarts, 0, "{err}");
    assert_eq!(rows.last().unwrap().dropped_chunks, 0, "{err}");
    assert_stored_records_valid(&dir, &w);
}
