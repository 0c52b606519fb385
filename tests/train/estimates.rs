//! Training on someone's estimates of E (`--empowerment-from`): estimates equal to the
//! exact values give the exact run's bits, other estimates another run, and a file that
//! misses a state, a family or a form without E are refused before anything starts.

use fulcrum_empowerment::request::{objects_or_default, tool_sel};
use fulcrum_empowerment::{Engine, Limits, Method};

use super::*;

/// `state,horizon,estimate` for every state of `world`'s default channel at the
/// horizons 1..=H, each value `f(exact E^h)` written so that it reads back to the same
/// f64 (the engine here is the library, not the run's service).
fn estimates(world: &str, f: impl Fn(f64) -> f64) -> String {
    let w = fulcrum_world::load_world(world).unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let set = objects_or_default(&w, None).unwrap();
    let tool = tool_sel(&w, &e, None, &set).unwrap();
    let top = w
        .empowerment
        .horizon_unequipped
        .max(w.empowerment.horizon_equipped);
    let mut out = String::from("row,state,horizon,estimate\n");
    for h in 1..=top {
        let v = e.values(tool, &set, h, Method::Dp).unwrap();
        for (i, s) in e.space.states().iter().enumerate() {
            let hex: String = s.to_bytes().iter().map(|b| format!("{b:02x}")).collect();
            out.push_str(&format!("{i},{hex},{h},{:?}\n", f(v[i])));
        }
    }
    out
}

fn run_with(dir: &Path, extra: &[&str]) -> Vec<MetricsRow> {
    let common = [
        &["room", "--actors", "1", "--steps", "768", "--seed", "7"][..],
        SMALL,
        extra,
    ]
    .concat();
    let (s, err, _) = finish(
        train(&[&common[..], &["--out", dir.to_str().unwrap()]].concat()),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    read_metrics(&dir.join("metrics.csv")).unwrap()
}

#[test]
fn exact_estimates_give_the_exact_run_and_others_another() {
    let files = TempDir::fresh("estimates");
    std::fs::create_dir_all(&files).unwrap();
    let exact = files.join("exact.csv");
    std::fs::write(&exact, estimates("room", |v| v)).unwrap();
    let high = files.join("high.csv");
    // One bit too many where E is positive: the potential's differences change.
    std::fs::write(
        &high,
        estimates("room", |v| if v > 0.0 { v + 1.0 } else { v }),
    )
    .unwrap();
    let (a, b, c) = (
        TempDir::fresh("est-a"),
        TempDir::fresh("est-b"),
        TempDir::fresh("est-c"),
    );
    let ra = run_with(&a, &[]);
    let rb = run_with(&b, &["--empowerment-from", exact.to_str().unwrap()]);
    let rc = run_with(&c, &["--empowerment-from", high.to_str().unwrap()]);
    assert_eq!(ra.len(), 6);
    let bits = |r: &[MetricsRow]| r.iter().map(deterministic).collect::<Vec<_>>();
    assert_eq!(bits(&ra), bits(&rb));
    assert_ne!(
        ra.iter().map(|r| r.intrinsic_mean).collect::<Vec<_>>(),
        rc.iter().map(|r| r.intrinsic_mean).collect::<Vec<_>>()
    );
    // The run keeps its copy and says where it came from; beta stays the exact one's.
    let copy = std::fs::read_to_string(b.join("empowerment-estimates.csv")).unwrap();
    assert_eq!(copy, std::fs::read_to_string(&exact).unwrap());
    let cb = std::fs::read_to_string(b.join("config.toml")).unwrap();
    let ca = std::fs::read_to_string(a.join("config.toml")).unwrap();
    assert!(
        cb.contains("empowerment_from = ") && cb.contains("exact.csv"),
        "{cb}"
    );
    let beta = |c: &str| {
        c.lines()
            .find(|l| l.starts_with("beta ="))
            .unwrap()
            .to_string()
    };
    assert_eq!(beta(&ca), beta(&cb));
    // A resume serves the run's copy: the file it came from may be gone.
    std::fs::remove_file(&high).unwrap();
    let (s, err, _) = finish(
        train(&["--resume", c.to_str().unwrap(), "--steps", "1024"]),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    assert_eq!(read_metrics(&c.join("metrics.csv")).unwrap().len(), 8);
    for d in [&a, &b, &c, &files] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn bad_estimates_are_refused_before_anything_starts() {
    let files = TempDir::fresh("estimates-bad");
    std::fs::create_dir_all(&files).unwrap();
    let full = estimates("room", |v| v);
    // The last line dropped: one state misses its estimate at the largest horizon.
    let short = files.join("short.csv");
    let mut lines: Vec<&str> = full.lines().collect();
    lines.pop();
    std::fs::write(&short, lines.join("\n")).unwrap();
    let garbled = files.join("garbled.csv");
    std::fs::write(&garbled, full.replacen(",0.0\n", ",lots\n", 1)).unwrap();
    let out = files.join("run");
    let o = out.to_str().unwrap();
    let s = short.to_str().unwrap();
    for (args, says) in [
        (
            vec!["room", "--empowerment-from", s, "--out", o],
            "has no estimate at horizon",
        ),
        (
            vec![
                "room",
                "--empowerment-from",
                garbled.to_str().unwrap(),
                "--out",
                o,
            ],
            "estimate 'lots' is not a finite number of bits",
        ),
        (
            vec!["toolbox", "--empowerment-from", s, "--out", o],
            "--empowerment-from does not fit a world family",
        ),
        (
            vec![
                "room",
                "--no-empowerment",
                "--empowerment-from",
                s,
                "--out",
                o,
            ],
            "--empowerment-from needs a form that uses E",
        ),
    ] {
        let r = crate::util::run(&[&["train"][..], &args].concat());
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(
            !out.join("config.toml").exists(),
            "{args:?} left a run behind"
        );
    }
    let _ = std::fs::remove_dir_all(&files);
}
