//! Empowerment of stochastic worlds against closed forms worked by hand, the NumPy
//! brute force of `scripts/reference/stochastic_empowerment.py` (its output committed in
//! `tests/reference/stochastic_reference.txt`), the engine's own brute force, and the
//! deterministic engine wherever chance is written out as none.

use fulcrum_empowerment::capacity::{binary_capacity, blahut_arimoto, GAP_BITS};
use fulcrum_empowerment::{Engine, Limits, Method, ToolSel};
use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::{load_world, parse_world, ObjectSet, State, World};

fn world(text: &str) -> World {
    parse_world(text, "test.toml").unwrap()
}

fn value_at(e: &Engine, tool: ToolSel, set: &ObjectSet, h: u32, s: &State) -> (f64, f64) {
    let id = e.state_id(s).unwrap();
    let c = e.values_at(tool, set, h, &[id], Method::Dp).unwrap()[0];
    (c.bits, c.gap)
}

// Holding the axe beside the tree, the only way to change the tree in h = 3 steps is
// apply, select, E, which fells it with probability p; every other sequence leaves it
// intact. So the channel has two rows, P(destroyed) = 0 and p: the Z-channel. With input
// 1 taken with probability t, I = h(t p) - t h(p); dI/dt = 0 at
// t p = 1 / (1 + 2^(h(p)/p)), and there I = log2(1 + 2^(-h(p)/p))
// = log2(1 + p (1 - p)^((1 - p) / p)). At p = 0.8: 0.2^0.25 = 0.668740,
// 0.8 * 0.668740 = 0.534992, log2(1.534992) = 0.618231.
#[test]
fn one_apply_with_probability_p_is_a_z_channel() {
    for p in [0.8, 0.5, 0.3] {
        let w = world(&format!(
            "name = \"z\"\nmap = \"\"\"\n#####\n#@aT#\n#####\n\"\"\"\n[tools]\na = \"axe\"\n\
             [[rules]]\ntool = \"axe\"\ntarget = \"tree\"\nfrom = \"intact\"\nto = \"destroyed\"\n\
             range = 1\np = {p}\n"
        ));
        let e = Engine::new(&w, Limits::default()).unwrap();
        let mut s = w.initial;
        s.x = 2;
        s.inventory = 1;
        let tree = ObjectSet::Objects(vec![0]);
        let (v, gap) = value_at(&e, ToolSel::Tool(0), &tree, 3, &s);
        let z: f64 = (1.0 + p * (1.0f64 - p).powf((1.0 - p) / p)).log2();
        assert!((v - z).abs() < 1e-12, "p = {p}: {v} against {z}");
        assert_eq!(gap, 0.0);
        if p == 0.8 {
            assert!((v - 0.618231).abs() < 1e-6);
        }
        // Two steps cannot fell it: exactly 0.
        assert_eq!(value_at(&e, ToolSel::Tool(0), &tree, 2, &s).0, 0.0);
    }
}

// An open room, D = agent, h = 1, slip q: "stay" (apply) is exact, and each move lands
// where meant with 1 - q and on each other neighbour with q / 3. By symmetry the four
// moves share one weight. The capacity of a channel with one noiseless row (the centre)
// and four rows of entropy H that are permutations of each other over the four
// neighbours is log2(1 + 4 * 2^(-H)) = log2(1 + 2^(2 - H)), with
// H = -(1 - q) log2(1 - q) - q log2(q / 3). At q = 0.1: H = 0.136803 + 0.490689
// = 0.627492, 2^(1.372508) = 2.589244, log2(3.589244) = 1.843664.
#[test]
fn slip_in_an_open_room() {
    for q in [0.1, 0.3] {
        let w = world(&format!(
            "name = \"r\"\nmap = \"\"\"\n#######\n#.....#\n#.....#\n#..@..#\n#.....#\n#.....#\n\
             #######\n\"\"\"\n[dynamics]\nslip = {q}\n"
        ));
        let e = Engine::new(&w, Limits::default()).unwrap();
        let (v, gap) = value_at(&e, ToolSel::All, &ObjectSet::Agent, 1, &w.initial);
        let hq = -(1.0 - q) * (1.0f64 - q).log2() - q * (q / 3.0f64).log2();
        let want = (1.0 + (2.0 - hq).exp2()).log2();
        assert!(gap < GAP_BITS, "{gap}");
        assert!(
            v <= want + 1e-12 && v + gap >= want - 1e-12,
            "q = {q}: {v} + {gap} against {want}"
        );
        assert!((v - want).abs() < 1e-9);
        if q == 0.1 {
            assert!((v - 1.843664).abs() < 1e-6);
        }
    }
}

// Blahut-Arimoto's bounds bracket the capacity: every input distribution's I lies below
// the upper bound (bits + gap), and the closed form of two outputs lies inside them.
#[test]
fn blahut_arimoto_bounds_bracket_the_capacity() {
    let mut seed = 1u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..20 {
        let (n, m) = (5, 4);
        let mut w = vec![0.0; n * m];
        for r in w.chunks_mut(m) {
            r.iter_mut().for_each(|x| *x = rnd() + 0.01);
            let t: f64 = r.iter().sum();
            r.iter_mut().for_each(|x| *x /= t);
        }
        let c = blahut_arimoto(&w, m, GAP_BITS);
        assert!(c.gap < GAP_BITS);
        for _ in 0..50 {
            let mut p: Vec<f64> = (0..n).map(|_| rnd()).collect();
            let t: f64 = p.iter().sum();
            p.iter_mut().for_each(|x| *x /= t);
            let q: Vec<f64> = (0..m)
                .map(|y| (0..n).map(|x| p[x] * w[x * m + y]).sum())
                .collect();
            let i: f64 = (0..n)
                .map(|x| {
                    p[x] * (0..m)
                        .map(|y| w[x * m + y] * (w[x * m + y] / q[y]).log2())
                        .sum::<f64>()
                })
                .sum();
            assert!(i <= c.bits + c.gap + 1e-12, "I = {i} above {c:?}");
        }
    }
    // Two outputs: the closed form between the bounds, e.g. rows 0.2 and 0.7.
    let c = blahut_arimoto(&[0.8, 0.2, 0.3, 0.7], 2, GAP_BITS);
    let exact = binary_capacity(0.2, 0.7);
    assert!(c.bits <= exact + 1e-12 && exact <= c.bits + c.gap + 1e-12);
}

/// The reference file: (world, D, h, x, y, inventory, mode, tree) -> bits.
fn reference() -> Vec<(String, String, u32, [u8; 5], f64)> {
    let text = include_str!("reference/stochastic_reference.txt");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let n = |i: usize| f[i].parse::<u8>().unwrap();
            (
                f[0].to_string(),
                f[1].to_string(),
                f[2].parse().unwrap(),
                [n(3), n(4), n(5), n(6), n(7)],
                f[8].parse().unwrap(),
            )
        })
        .collect()
}

// Every state of two tiny worlds, h = 1..4, D = the tree and D = the agent: the engine
// agrees with the NumPy brute force to 1e-9 bits, and the state spaces are the same.
#[test]
fn agrees_with_the_numpy_brute_force() {
    let refs = reference();
    assert!(refs.len() > 200, "{}", refs.len());
    for name in ["tiny-axe", "tiny-corridor"] {
        let path = format!("{}/tests/reference/{name}.toml", env!("CARGO_MANIFEST_DIR"));
        let w = load_world(&path).unwrap();
        let e = Engine::new(&w, Limits::default()).unwrap();
        let tool = if w.tools.is_empty() {
            ToolSel::All
        } else {
            ToolSel::Tool(0)
        };
        for (dname, set) in [
            ("tree", ObjectSet::Objects(vec![0])),
            ("agent", ObjectSet::Agent),
        ] {
            for h in 1..=4 {
                let rows: Vec<_> = refs
                    .iter()
                    .filter(|r| r.0 == name && r.1 == dname && r.2 == h)
                    .collect();
                if rows.is_empty() {
                    continue;
                }
                assert_eq!(rows.len(), e.space.len(), "{name}: the same states");
                let ids: Vec<u32> = rows
                    .iter()
                    .map(|r| {
                        let f = r.3;
                        let mut s: State = w.initial;
                        s.x = f[0];
                        s.y = f[1];
                        s.inventory = f[2] as u16;
                        s.mode = f[3];
                        if !w.objects.is_empty() {
                            s.objects[0] = f[4] as u16;
                        }
                        e.state_id(&s).unwrap()
                    })
                    .collect();
                let got = e.values_at(tool, &set, h, &ids, Method::Dp).unwrap();
                for (r, c) in rows.iter().zip(&got) {
                    assert!(
                        (c.bits - r.4).abs() < 1e-9,
                        "{name} {dname} h={h} {:?}: {} against {}",
                        r.3,
                        c.bits,
                        r.4
                    );
                    assert!(c.gap < GAP_BITS);
                }
            }
        }
    }
}

// Distribution propagation with its reductions against the engine's brute force (every
// sequence, every outcome, Blahut-Arimoto without the closed form) on the built-in
// stochastic worlds.
#[test]
fn agrees_with_brute_force_on_the_slip_worlds() {
    for (name, h) in [("exp1-tree-slip", 3), ("exp2-slip", 3)] {
        let w = load_world(name).unwrap();
        let e = Engine::new(&w, Limits::default()).unwrap();
        let ids: Vec<u32> = (0..e.space.len() as u32).step_by(173).collect();
        let sets = [
            ObjectSet::Objects(vec![0]),
            ObjectSet::Objects((0..w.objects.len()).collect()),
            ObjectSet::Agent,
        ];
        for set in &sets {
            for j in 0..w.tools.len().min(2) {
                let tool = ToolSel::Tool(j);
                let fast = e.values_at(tool, set, h, &ids, Method::Dp).unwrap();
                let slow = e.values_at(tool, set, h, &ids, Method::Enumerate).unwrap();
                for (k, (a, b)) in fast.iter().zip(&slow).enumerate() {
                    assert!(
                        (a.bits - b.bits).abs() < 2e-9,
                        "{name} state {}: {a:?} against {b:?}",
                        ids[k]
                    );
                }
            }
        }
    }
}

/// `text` with chance written out as none: `slip = 0` and p = 1 on every default rule
/// of the tools in play.
fn with_explicit_certainty(w: &World) -> String {
    let mut text = w.source.clone();
    text.push_str("\n[dynamics]\nslip = 0\n");
    for r in fulcrum_world::world::default_rules() {
        if !w.tools.iter().any(|t| t.kind == r.tool) {
            continue;
        }
        let range = match r.range {
            fulcrum_world::Range::Adjacent => "1",
            fulcrum_world::Range::Bolt => "\"bolt\"",
        };
        text.push_str(&format!(
            "\n[[rules]]\ntool = \"{}\"\ntarget = \"{}\"\nfrom = \"{}\"\nto = \"{}\"\nrange = {range}\np = 1\n",
            r.tool,
            r.target.name(),
            fulcrum_world::world::cond_name(r.target, r.from),
            fulcrum_world::world::cond_name(r.target, r.to),
        ));
    }
    text
}

// slip = 0 and p = 1 written out give today's values bit for bit: the matrices of the
// five built-in worlds and of generated worlds.
#[test]
fn certainty_written_out_changes_nothing() {
    let mut worlds: Vec<World> = fulcrum_world::builtin::NAMES
        .iter()
        .map(|n| load_world(n).unwrap())
        .collect();
    for seed in 0..3 {
        let text = generate(&GenParams {
            width: 8,
            height: 6,
            tools: 2,
            objects: 2,
            rock: 0.1,
            seed,
        })
        .unwrap();
        worlds.push(parse_world(&text, "generated").unwrap());
    }
    for w in &worlds {
        let w2 = parse_world(&with_explicit_certainty(w), "explicit").unwrap();
        assert!(!w2.is_stochastic());
        let e = Engine::new(w, Limits::default()).unwrap();
        let e2 = Engine::new(&w2, Limits::default()).unwrap();
        assert_eq!(e.space.states(), e2.space.states());
        let cols: Vec<ObjectSet> = (0..w.objects.len())
            .map(|i| ObjectSet::Objects(vec![i]))
            .collect();
        let (hu, he) = (
            w.empowerment.horizon_unequipped.min(6),
            w.empowerment.horizon_equipped.min(6),
        );
        let m = e.matrix(&cols, hu, he, Method::Dp).unwrap();
        let m2 = e2.matrix(&cols, hu, he, Method::Dp).unwrap();
        assert_eq!(m, m2, "{}", w.name);
        assert_eq!(m2.gap, 0.0);
    }
}

// Phi = sum over h of E^h, as the service's horizon-potential table gives it, and the
// per-inventory table.
#[test]
fn lookup_tables_of_a_stochastic_world() {
    let path = format!(
        "{}/tests/reference/tiny-axe.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let w = load_world(&path).unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let tree = ObjectSet::Objects(vec![0]);
    let axe = ToolSel::Tool(0);
    let phi = e.lookup_values(axe, &tree, 4, 3, true).unwrap();
    let table = e.lookup_values(axe, &tree, 4, 3, false).unwrap();
    let by_h: Vec<Vec<f64>> = (1..=4)
        .map(|h| e.values(axe, &tree, h, Method::Dp).unwrap())
        .collect();
    for i in 0..e.space.len() {
        let sum: f64 = by_h.iter().map(|v| v[i]).sum();
        assert!((phi[i] as f64 - sum).abs() < 1e-5);
        let h = if e.space.state(i as u32).holds(0) {
            3
        } else {
            4
        };
        assert_eq!(table[i], by_h[h - 1][i] as f32);
    }
    // The prefilter's zeros: with the tree down nothing can change it.
    for (i, s) in e.space.states().iter().enumerate() {
        if s.objects[0] == 2 {
            assert_eq!(table[i], 0.0);
        }
    }
    assert!(table.iter().any(|&v| v > 0.0));
}

// A channel too large for the memory limit is refused with a sentence, not computed
// until the machine runs out: exp1-tree-slip, D = agent, h = 6, with little to spare.
#[test]
fn a_channel_over_the_memory_limit_is_refused() {
    let w = load_world("exp1-tree-slip").unwrap();
    // What enumeration asks of a stochastic space (its estimate per state, with four
    // outcomes of 12 bytes per action), and 64 KiB more.
    let n = Engine::new(&w, Limits::default()).unwrap().space.len();
    let na = w.num_actions();
    let per_state = fulcrum_empowerment::space::bytes_per_state(na) + na * 48;
    let tight = Limits {
        max_bytes: n * per_state + (64 << 10),
    };
    let e = Engine::new(&w, tight).unwrap();
    let id = e.state_id(&w.parse_state("agent=5,3").unwrap()).unwrap();
    let err = e
        .values_at(ToolSel::Tool(0), &ObjectSet::Agent, 6, &[id], Method::Dp)
        .unwrap_err();
    let msg = err.to_string();
    assert!(
        matches!(
            err,
            fulcrum_empowerment::EngineError::ChannelTooLarge { .. }
        ),
        "{msg}"
    );
    assert!(
        msg.contains("memory limit") && msg.contains("horizon 6"),
        "{msg}"
    );
}

// `--empowerment-model deterministic`: the slip worlds with nothing left to chance are
// the paper's worlds they were written from (the same map, tools and horizons; a
// different file): the same states in the same order and the same service tables, bit
// for bit. Every state the noisy dynamics reach is one of them, so a service computed
// on the twin answers every state an actor of the noisy world meets.
#[test]
fn the_deterministic_twin_of_a_slip_world_is_the_world_it_was_written_from() {
    for (noisy, plain) in [("exp1-tree-slip", "exp1-tree"), ("exp2-slip", "exp2")] {
        let n = load_world(noisy).unwrap();
        let twin = n.without_chance();
        assert!(n.is_stochastic() && !twin.is_stochastic());
        assert_eq!(twin.content_hash(), n.content_hash(), "{noisy}");
        assert_eq!(twin.slip, 0.0);
        assert!(twin.rules.iter().all(|r| r.p == 1.0));
        let p = load_world(plain).unwrap();
        let (et, ep) = (
            Engine::new(&twin, Limits::default()).unwrap(),
            Engine::new(&p, Limits::default()).unwrap(),
        );
        assert_eq!(et.space.states(), ep.space.states(), "{noisy}");
        let en = Engine::new(&n, Limits::default()).unwrap();
        assert_eq!(en.space.len(), et.space.len(), "{noisy}");
        assert!(en.space.states().iter().all(|s| et.space.id(s).is_some()));
        let set = ObjectSet::Objects(vec![0]);
        let tool = ToolSel::Tool(0);
        let (hu, he) = (
            p.empowerment.horizon_unequipped,
            p.empowerment.horizon_equipped,
        );
        let a = et.lookup_values(tool, &set, hu, he, true).unwrap();
        let b = ep.lookup_values(tool, &set, hu, he, true).unwrap();
        assert!(
            a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "{noisy}"
        );
        // And the noise lowers E somewhere: the twin is not the noisy world's table.
        let c = en.lookup_values(tool, &set, hu, he, true).unwrap();
        assert!(c.iter().zip(&a).any(|(x, y)| x < y), "{noisy}");
    }
}
