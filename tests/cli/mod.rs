//! The command line: JSON shapes the README shows, values of worlds/EXPECTED.md through the
//! binary, bad input (one sentence, exit code 2), and files written.

use serde_json::Value;

/// Stochastic worlds through the binary.
mod family;
mod stochastic;

use crate::util::{run as fulcrum, TempDir};

pub(super) fn json(args: &[&str]) -> Value {
    let out = fulcrum(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("valid JSON on stdout")
}

/// Runs and fails with exit code 2 and one line on stderr mentioning `needle`.
pub(super) fn bad_input(args: &[&str], needle: &str) {
    let out = fulcrum(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(
        err.contains(needle),
        "{args:?}: '{err}' should mention '{needle}'"
    );
    assert!(
        !err.contains("panicked") && !err.contains("backtrace"),
        "{err}"
    );
}

#[test]
fn matrix_json_exp1_tree() {
    let v = json(&[
        "empowerment",
        "matrix",
        "exp1-tree",
        "--horizon-unequipped",
        "8",
        "--horizon-equipped",
        "3",
        "--joint",
        "tree+wall",
        "--json",
    ]);
    assert_eq!(v["world"], "exp1-tree");
    assert_eq!(v["states"], 8880);
    assert_eq!(v["normal_states"], 2052);
    assert_eq!(
        v["tools"],
        serde_json::json!(["axe", "pickaxe", "tin_opener", "key"])
    );
    assert_eq!(
        v["columns"],
        serde_json::json!(["tree", "wall", "tree+wall"])
    );
    let m = v["matrix"].as_array().unwrap();
    // EXPECTED.md: 96/2052 and 72/2052.
    assert!((m[0][0].as_f64().unwrap() - 96.0 / 2052.0).abs() < 1e-12);
    assert!((m[1][1].as_f64().unwrap() - 72.0 / 2052.0).abs() < 1e-12);
    assert_eq!(m[2][0].as_f64(), Some(0.0));
    assert_eq!(v["selection"]["tree"], "axe");
    assert_eq!(v["selection"]["wall"], "pickaxe");
    assert_eq!(v["selection"]["tree+wall"], "axe");
    assert!(v["elapsed_ms"].as_f64().unwrap() > 0.0);
}

/// With no horizon option the matrix is tool selection's: one horizon, the world's
/// horizon where the tool is not held (exp3's 10), for every state and row; its values
/// are `tests/reference/exp3_bruteforce.py --horizon 10`'s.
#[test]
fn the_default_matrix_is_the_selections() {
    let v = json(&["empowerment", "matrix", "exp3", "--json"]);
    assert_eq!(
        (
            v["horizon_unequipped"].as_u64(),
            v["horizon_equipped"].as_u64()
        ),
        (Some(10), Some(10))
    );
    assert_eq!(v["tools"], serde_json::json!(["key", "axe"]));
    let m = v["matrix"].as_array().unwrap();
    assert!((m[0][1].as_f64().unwrap() - 2.042360751798079).abs() < 1e-9);
    assert!((m[1][1].as_f64().unwrap() - 2.0061106993148887).abs() < 1e-9);
    // Rows that switch to 5 where their tool is held rank the boulder's column the
    // other way (worlds/EXPECTED.md); auto never uses them.
    assert_eq!(v["selection"]["boulder"], "key");
    let mixed = json(&[
        "empowerment",
        "matrix",
        "exp3",
        "--horizon-equipped",
        "5",
        "--json",
    ]);
    assert_eq!(mixed["selection"]["boulder"], "axe");
    let out = fulcrum(&["empowerment", "matrix", "exp3"]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("averaged), h = 10, "), "{text}");
}

#[test]
fn matrix_selects_none_for_a_zero_column() {
    // In exp1-tree the tin opener and key act on nothing: a column of the key's own
    // world objects still has the axe; `--horizon 0` makes every entry zero.
    let v = json(&[
        "empowerment",
        "matrix",
        "exp1-tree",
        "--horizon",
        "0",
        "--json",
    ]);
    assert_eq!(v["selection"]["tree"], Value::Null);
}

#[test]
fn matrix_human_output_marks_the_selection() {
    let out = fulcrum(&[
        "empowerment",
        "matrix",
        "exp2",
        "--horizon-unequipped",
        "5",
        "--horizon-equipped",
        "6",
        "--joint",
        "boulder+door",
    ]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("h = 5 unequipped / 6 equipped"), "{text}");
    assert!(text.contains("0.209375*"), "{text}");
    assert!(
        text.contains("selection: boulder -> wand, door -> wand, boulder+door -> wand"),
        "{text}"
    );
}

#[test]
fn landscape_json_exp1_beacon() {
    let v = json(&[
        "empowerment",
        "landscape",
        "exp1-tree",
        "--tool",
        "axe",
        "--objects",
        "tree",
        "--horizon",
        "8",
        "--json",
    ]);
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(12), Some(8))
    );
    assert_eq!(v["tool"], "axe");
    assert_eq!(v["objects"], serde_json::json!(["tree"]));
    assert_eq!(v["horizon"], 8);
    let vals = &v["values"];
    assert_eq!(vals[2][3].as_f64(), Some(1.0));
    assert_eq!(vals[1][4].as_f64(), Some(1.0));
    assert!(vals[2][4].is_null(), "the axe's own cell has no value");
    assert_eq!(vals[5][5].as_f64(), Some(0.0));
}

#[test]
fn landscape_default_horizon_follows_the_inventory() {
    // exp1-tree's [empowerment]: 8 unequipped, 3 equipped.
    let v = json(&[
        "empowerment",
        "landscape",
        "exp1-tree",
        "--tool",
        "axe",
        "--objects",
        "tree",
        "--holding",
        "axe",
        "--json",
    ]);
    assert_eq!(v["horizon"], 3);
    assert_eq!(v["values"][2][8].as_f64(), Some(1.0));
}

#[test]
fn trace_json_exp3_axe() {
    let v = json(&[
        "empowerment",
        "trace",
        "exp3",
        "--actions",
        "S,E,E,E,E,N,N,apply,axe,E",
        "--tool",
        "axe",
        "--objects",
        "door",
        "--horizon",
        "3",
        "--json",
    ]);
    let steps = v["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 11);
    assert_eq!(steps[0]["t"], 0);
    assert!(steps[0]["action"].is_null());
    assert_eq!(steps[1]["action"], "S");
    let vals: Vec<f64> = steps.iter().map(|s| s["value"].as_f64().unwrap()).collect();
    assert_eq!(&vals[7..], &[1.0, 1.0, 1.0, 0.0]);
}

#[test]
fn query_local() {
    let v = json(&[
        "empowerment",
        "query",
        "exp3",
        "--state",
        "agent=5,3 holding=key door=open",
        "--tool",
        "key",
        "--objects",
        "door",
        "--horizon",
        "3",
        "--json",
    ]);
    assert_eq!(v["value"].as_f64(), Some(1.0));
    // The closed form: with the agent as the object, the cells within n = 2 steps of
    // (3,3) number 2n^2 + 2n + 1 = 13 (all floor; the axe's cell can be entered).
    let v = json(&[
        "empowerment",
        "query",
        "exp1-tree",
        "--state",
        "agent=3,3",
        "--tool",
        "all",
        "--objects",
        "agent",
        "--horizon",
        "2",
        "--json",
    ]);
    assert!((v["value"].as_f64().unwrap() - 13f64.log2()).abs() < 1e-12);
}

#[test]
fn query_states_file() {
    let d = TempDir::new("states");
    let f = d.join("states.txt");
    std::fs::write(
        &f,
        "# exp1-tree states\nagent=3,2\n\nagent=8,2 holding=axe\nagent=1,1\n",
    )
    .unwrap();
    let v = json(&[
        "empowerment",
        "query",
        "exp1-tree",
        "--states-file",
        f.to_str().unwrap(),
        "--tool",
        "axe",
        "--objects",
        "tree",
        "--json",
    ]);
    let vals: Vec<f64> = v["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x["value"].as_f64().unwrap())
        .collect();
    // Next to the axe (h = 8): 1; next to the tree holding the axe (h = 3): 1; a corner: 0.
    assert_eq!(vals, vec![1.0, 1.0, 0.0]);
}

#[test]
fn method_enumerate_agrees_through_the_cli() {
    let a = json(&[
        "empowerment",
        "landscape",
        "exp2",
        "--tool",
        "wand",
        "--objects",
        "boulder,door",
        "--horizon",
        "4",
        "--holding",
        "wand",
        "--json",
    ]);
    let b = json(&[
        "empowerment",
        "landscape",
        "exp2",
        "--tool",
        "wand",
        "--objects",
        "boulder,door",
        "--horizon",
        "4",
        "--holding",
        "wand",
        "--method",
        "enumerate",
        "--json",
    ]);
    assert_eq!(a["values"], b["values"]);
}

#[test]
fn world_show_and_generate() {
    let v = json(&["world", "show", "exp2", "--json"]);
    assert_eq!(v["states"], 10988);
    assert_eq!(v["actions"].as_array().unwrap().len(), 9);
    let d = TempDir::new("gen");
    let f = d.join("g.toml");
    let out = fulcrum(&[
        "world",
        "generate",
        "--width",
        "9",
        "--height",
        "7",
        "--tools",
        "2",
        "--objects",
        "2",
        "--seed",
        "5",
        "--out",
        f.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json(&["world", "show", f.to_str().unwrap(), "--json"]);
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(9), Some(7))
    );
    assert_eq!(v["tools"].as_array().unwrap().len(), 2);
    assert_eq!(v["objects"].as_array().unwrap().len(), 2);
    // Same seed, same file.
    let a = fulcrum(&["world", "generate", "--seed", "5"]).stdout;
    let b = fulcrum(&["world", "generate", "--seed", "5"]).stdout;
    assert_eq!(a, b);
}

#[test]
fn bad_input_is_one_sentence_and_exit_code_2() {
    bad_input(
        &["empowerment", "matrix", "no-such-world"],
        "unknown world 'no-such-world'",
    );
    bad_input(
        &[
            "empowerment",
            "landscape",
            "exp1-tree",
            "--tool",
            "hammer",
            "--objects",
            "tree",
        ],
        "unknown tool 'hammer'",
    );
    bad_input(
        &[
            "empowerment",
            "landscape",
            "exp1-tree",
            "--tool",
            "axe",
            "--objects",
            "rock",
        ],
        "unknown object 'rock'",
    );
    bad_input(
        &["empowerment", "matrix", "exp1-tree", "--horizon", "1000"],
        "horizon 1000 is too large",
    );
    bad_input(
        &[
            "empowerment",
            "query",
            "exp1-tree",
            "--state",
            "agent=0,0",
            "--tool",
            "axe",
            "--objects",
            "tree",
        ],
        "rock",
    );
    bad_input(
        &[
            "empowerment",
            "query",
            "exp1-tree",
            "--state",
            "agent=4,2",
            "--tool",
            "axe",
            "--objects",
            "tree",
        ],
        "picked up",
    );
    bad_input(
        &[
            "empowerment",
            "trace",
            "exp3",
            "--actions",
            "N,jump",
            "--tool",
            "key",
            "--objects",
            "door",
        ],
        "unknown action 'jump'",
    );
    bad_input(
        &[
            "empowerment",
            "matrix",
            "exp2",
            "--horizon",
            "9",
            "--method",
            "enumerate",
        ],
        "the enumerate method at horizon 9",
    );
    bad_input(&["world", "generate", "--width", "2"], "a world 2 wide");
    // A world file with a mistake: file, line and column.
    let d = TempDir::new("badworld");
    let f = d.join("bad.toml");
    std::fs::write(
        &f,
        "name = \"bad\"\nmap = \"\"\"\n#####\n#@.X#\n#####\n\"\"\"\n",
    )
    .unwrap();
    bad_input(
        &["world", "show", f.to_str().unwrap()],
        "bad.toml:4:4: unknown glyph 'X'",
    );
}

#[test]
fn a_state_space_over_the_memory_limit_is_refused_before_it_starts() {
    // A 64x64 room with many boulders cannot be enumerated on any machine: the refusal
    // names the estimate.
    let d = TempDir::new("huge");
    let f = d.join("huge.toml");
    let out = fulcrum(&[
        "world",
        "generate",
        "--width",
        "64",
        "--height",
        "64",
        "--tools",
        "16",
        "--objects",
        "16",
        "--seed",
        "1",
        "--out",
        f.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let out = crate::util::fulcrum()
        .args(["empowerment", "matrix", f.to_str().unwrap()])
        .env("FULCRUM_MAX_MEMORY", "64MiB")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("over the memory limit of 64.0 MiB"), "{err}");
}

#[test]
fn landscape_and_trace_pictures_are_written() {
    let d = TempDir::new("png");
    let l = d.join("landscape.png");
    let t = d.join("trace.png");
    let out = fulcrum(&[
        "empowerment",
        "landscape",
        "exp1-tree",
        "--tool",
        "axe",
        "--objects",
        "tree",
        "--horizon",
        "8",
        "--png",
        l.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = fulcrum(&[
        "empowerment",
        "trace",
        "exp3",
        "--tool",
        "key",
        "--objects",
        "door",
        "--horizon",
        "3",
        "--actions",
        "N,N,E,E,E,E,S,apply,key,E,E",
        "--png",
        t.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for p in [&l, &t] {
        let bytes = std::fs::read(p).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", p.display());
        // IHDR width and height: a real picture, not an empty one.
        let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
        let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
        assert!(w >= 200 && h >= 150, "{}: {w}x{h}", p.display());
    }
    // Nothing else left in the directory (no temp files).
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 2);
}

#[test]
fn the_matrix_picture_has_a_row_per_tool() {
    let d = TempDir::new("matrix-png");
    let m = d.join("matrix.png");
    let out = fulcrum(&[
        "empowerment",
        "matrix",
        "exp2",
        "--joint",
        "boulder+door",
        "--png",
        m.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&m).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    // Height: 64 px of title and header, 42 px per tool (exp2 has 4), 40 px of note.
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!(h, 64 + 4 * 42 + 40);
    // Width: at least three 130 px columns.
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    assert!(w >= 3 * 130, "{w}");
}

#[test]
fn record_refuses_a_directory_without_a_run() {
    let d = TempDir::new("record-none");
    std::fs::create_dir_all(&d).unwrap();
    let out = fulcrum(&["record", d.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("no config.toml there"), "{err}");
}

#[cfg(not(feature = "multihost"))]
#[test]
fn multihost_commands_say_which_build_they_need() {
    for args in [
        &["train", "room", "--listen", "127.0.0.1:7447"][..],
        &["actor-host", "--connect", "127.0.0.1:7447"][..],
        &["bridge", "--connect", "127.0.0.1:7447", "--run", "x"][..],
    ] {
        let out = fulcrum(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("needs fulcrum built with the multihost feature")
                && err.contains("--features multihost")
                && err.lines().count() == 1,
            "{err}"
        );
    }
}

/// `train --help` lists the flags between hosts only in a build that has them.
#[test]
fn train_help_lists_the_multihost_flags_only_where_they_work() {
    let out = fulcrum(&["train", "--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for flag in [
        "--listen",
        "--stall-timeout",
        "--session-timeout",
        "--zenoh-config",
    ] {
        assert_eq!(
            help.contains(flag),
            cfg!(feature = "multihost"),
            "{flag} in:\n{help}"
        );
    }
    // The rest is there either way.
    assert!(
        help.contains("--steps") && help.contains("--resume"),
        "{help}"
    );
}

#[test]
fn a_stall_timeout_without_listen_is_refused() {
    let out = fulcrum(&["train", "room", "--stall-timeout", "5"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--stall-timeout applies to runs with --listen"),
        "{err}"
    );
}

/// `conditions:boulder` through the binary, against hand counts on the boulder room
/// (agent (1,1), pickaxe (3,1), boulder (3,2) in a 5 x 3 floor), h = 3 along E, E.
#[test]
fn a_boulder_by_its_condition_against_hand_counts() {
    let world = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/worlds/boulder-room.toml"
    );
    let values = |objects: &str| -> (Value, Vec<f64>) {
        let v = json(&[
            "empowerment",
            "trace",
            world,
            "--objects",
            objects,
            "--horizon",
            "3",
            "--actions",
            "E,E",
            "--json",
        ]);
        let vals = v["steps"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["value"].as_f64().unwrap())
            .collect();
        (v["objects"].clone(), vals)
    };
    // By its condition: destroying takes apply, pickaxe, S from (3,1) holding the
    // pickaxe (t = 2), and 2 moves more before it is held (t = 0: 5 > 3; t = 1: 4 > 3).
    let (objects, cond) = values("conditions:boulder");
    assert_eq!(objects, serde_json::json!(["conditions:boulder"]));
    assert_eq!(cond, [0.0, 0.0, 1.0]);
    // By its cell: at t = 0 it can stay, be pushed to (4,2) (S, E, E) or to (3,3) (E, E
    // picking the pickaxe up, S): 3 outcomes; at t = 2 it can stay, go to (3,3) (S), to
    // (4,2) (W, S, E), to (2,2) (E, S, W) or be destroyed: 5 (the wall stops a second
    // push south).
    let (objects, full) = values("boulder");
    assert_eq!(objects, serde_json::json!(["boulder"]));
    assert!((full[0] - 3f64.log2()).abs() < 1e-12, "{full:?}");
    assert!((full[2] - 5f64.log2()).abs() < 1e-12, "{full:?}");
}
