//! Stochastic worlds through the binary: `world show` says what is left to chance, the
//! empowerment commands give values with their gaps, and bad `[dynamics]` or `p` values
//! are one sentence at file:line:col with exit code 2.

use super::{bad_input, json};
use crate::util::{run as fulcrum, TempDir};

#[test]
fn world_show_prints_the_chance() {
    let out = fulcrum(&["world", "show", "exp1-tree-slip"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("moves slip with probability 0.1"), "{text}");
    assert!(
        text.contains("axe tree intact -> destroyed (p 0.8)"),
        "{text}"
    );
    let v = json(&["world", "show", "exp2-slip", "--json"]);
    assert_eq!(v["stochastic"], true);
    assert_eq!(v["slip"], 0.1);
    assert_eq!(v["rule_p"].as_array().unwrap().len(), 4);
    let v = json(&["world", "show", "exp2", "--json"]);
    assert_eq!(v["stochastic"], false);
}

// The Z-channel of docs/world.md: holding the axe beside the tree of exp1-tree-slip
// (p = 0.8), h = 3, D = tree: log2(1 + 0.8 * 0.2^0.25) = 0.618231 bits, exact (gap 0).
#[test]
fn query_gives_the_capacity_and_its_gap() {
    let v = json(&[
        "empowerment",
        "query",
        "exp1-tree-slip",
        "--state",
        "agent=8,2 holding=axe",
        "--tool",
        "axe",
        "--objects",
        "tree",
        "--horizon",
        "3",
        "--json",
    ]);
    assert!(
        (v["value"].as_f64().unwrap() - 0.618231).abs() < 1e-6,
        "{v}"
    );
    assert_eq!(v["gap_bits"], 0.0);
    // The deterministic world: log2 2 = 1 bit, gap 0.
    let v = json(&[
        "empowerment",
        "query",
        "exp1-tree",
        "--state",
        "agent=8,2 holding=axe",
        "--tool",
        "axe",
        "--objects",
        "tree",
        "--horizon",
        "3",
        "--json",
    ]);
    assert_eq!(v["value"], 1.0);
    assert_eq!(v["gap_bits"], 0.0);
}

#[test]
fn bad_chance_is_one_sentence_and_exit_code_2() {
    let d = TempDir::new("badchance");
    let head = "name = \"t\"\nmap = \"\"\"\n#####\n#@aT#\n#####\n\"\"\"\n[tools]\na = \"axe\"\n";
    let cases = [
        ("[dynamics]\nslip = 1.5\n", "bad.toml:10:8: slip = 1.5"),
        ("[dynamics]\nstorm = 1\n", "bad.toml:10:1:"),
        (
            "[[rules]]\ntool = \"axe\"\ntarget = \"tree\"\nfrom = \"intact\"\nto = \"destroyed\"\nrange = 1\np = 2\n",
            "bad.toml:15:5: p = 2",
        ),
        (
            "[[rules]]\ntool = \"axe\"\ntarget = \"tree\"\nfrom = \"intact\"\nto = \"destroyed\"\nrange = \"bolt\"\np = 0.5\n",
            "bad.toml:14:9:",
        ),
    ];
    for (extra, needle) in cases {
        let path = d.join("bad.toml");
        std::fs::write(&path, format!("{head}{extra}")).unwrap();
        let p = path.to_str().unwrap().to_string();
        // Errors name the file as given.
        bad_input(&["world", "show", &p], &needle.replace("bad.toml", &p));
    }
}

/// `fulcrum serve` on a stochastic world as a child, until it prints "ready"; stopped
/// (SIGKILL of this child) when dropped.
struct Serve(std::process::Child);

impl Serve {
    fn start(world: &str, ns: &str, extra: &[&str]) -> Serve {
        use std::io::{BufRead, BufReader};
        let mut child = crate::util::fulcrum()
            .args(["serve", world, "--namespace", ns])
            .args(extra)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("fulcrum serve starts");
        let out = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for l in BufReader::new(out).lines().map_while(Result::ok) {
                let _ = tx.send(l);
            }
        });
        let serve = Serve(child);
        loop {
            match rx.recv_timeout(std::time::Duration::from_secs(120)) {
                Ok(l) if crate::util::is_ready(&l) => return serve,
                Ok(_) => {}
                Err(_) => panic!("fulcrum serve {world} did not become ready"),
            }
        }
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

// The service's LOOKUP table of exp1-tree-slip (its [empowerment]: the matrix selects the
// axe, D = tree, h = 8 / 3), and the horizon-sum table, equal the engine's, state by
// state; the shared-memory protocol is the deterministic worlds'.
#[test]
fn serve_answers_a_stochastic_world() {
    use fulcrum_empowerment::service::{Ask, Client};
    use fulcrum_empowerment::{Engine, Limits, ToolSel};
    use fulcrum_world::{load_world, ObjectSet};
    let w = load_world("exp1-tree-slip").unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let tree = ObjectSet::Objects(vec![w.object_index("tree").unwrap()]);
    let states: Vec<_> = e.space.states().to_vec();
    for sum in [false, true] {
        let ns = crate::util::namespace(if sum { "slip-sum" } else { "slip" });
        let extra: &[&str] = if sum { &["--horizon-sum"] } else { &[] };
        let _serve = Serve::start("exp1-tree-slip", &ns, extra);
        let mut c = Client::connect(&ns, &w, std::time::Duration::from_secs(30)).unwrap();
        let want = e.lookup_values(ToolSel::Tool(0), &tree, 8, 3, sum).unwrap();
        let got = c.values(Ask::Lookup, &states, 256).unwrap();
        assert_eq!(got.values, want, "horizon sum {sum}");
        assert!(want.iter().any(|&v| v > 0.0));
    }
}

// `serve --model deterministic` (what `train --empowerment-model deterministic` starts):
// the noisy world's actors are answered (the same hash) with the table of the map
// without its noise, which is exp1-tree's, a file written apart: state by state.
#[test]
fn serve_computes_a_noisy_world_as_if_deterministic_when_asked() {
    use fulcrum_empowerment::service::{Ask, Client};
    use fulcrum_empowerment::{Engine, Limits, ToolSel};
    use fulcrum_world::{load_world, ObjectSet};
    let noisy = load_world("exp1-tree-slip").unwrap();
    let plain = load_world("exp1-tree").unwrap();
    let e = Engine::new(&plain, Limits::default()).unwrap();
    let tree = ObjectSet::Objects(vec![plain.object_index("tree").unwrap()]);
    let states: Vec<_> = Engine::new(&noisy, Limits::default())
        .unwrap()
        .space
        .states()
        .to_vec();
    let ns = crate::util::namespace("slip-det");
    let _serve = Serve::start("exp1-tree-slip", &ns, &["--model", "deterministic"]);
    let mut c = Client::connect(&ns, &noisy, std::time::Duration::from_secs(30)).unwrap();
    let got = c.values(Ask::Lookup, &states, 256).unwrap();
    let want: Vec<f32> = {
        let t = e
            .lookup_values(ToolSel::Tool(0), &tree, 8, 3, false)
            .unwrap();
        states
            .iter()
            .map(|s| t[e.space.id(s).unwrap() as usize])
            .collect()
    };
    assert_eq!(got.values, want);
    let noisy_table = Engine::new(&noisy, Limits::default())
        .unwrap()
        .lookup_values(ToolSel::Tool(0), &tree, 8, 3, false)
        .unwrap();
    assert_ne!(
        got.values, noisy_table,
        "the service served the noisy channel"
    );
}
