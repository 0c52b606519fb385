//! Poisoned inputs: packed states, episode records and chunks that no actor of the
//! world could have written are refused with one line, and whatever is accepted the
//! dynamics and the observation take without a panic (proptest, bounded cases).

use fulcrum_contracts::chunk_check::{check_chunk, BadChunk};
use fulcrum_contracts::traj::{ChunkHeader, ChunkLayout, EnvRecord, Section, ENV_BYTES};
use fulcrum_contracts::valid::check_record;
use fulcrum_world::{load_world, State, World, BOULDER_DESTROYED};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A change made to a value under test.
type Edit<T> = Box<dyn Fn(&mut T)>;
/// A change made to a chunk's payload and header.
type ChunkEdit<'a> = Box<dyn Fn(&mut Vec<u8>, &mut ChunkHeader) + 'a>;

const WORLDS: [&str; 5] = ["exp1-tree", "exp1-wall", "exp2", "exp3", "room"];

fn one_line(e: impl std::fmt::Display) -> bool {
    let s = e.to_string();
    !s.is_empty() && !s.contains('\n')
}

/// States reached by a random walk of `steps` actions from the initial state.
fn walk(w: &World, seed: u64, steps: usize) -> Vec<State> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut s = w.initial;
    let mut out = vec![s];
    for _ in 0..steps {
        s = w.step(&s, rng.random_range(0..w.num_actions()) as u8);
        out.push(s);
    }
    out
}

#[test]
fn every_state_a_walk_reaches_is_valid() {
    for name in WORLDS {
        let w = load_world(name).unwrap();
        for seed in 0..20 {
            for s in walk(&w, seed, 400) {
                assert_eq!(w.check_state(&s), Ok(()), "{name}: {}", w.describe(&s));
            }
        }
    }
}

#[test]
fn each_kind_of_bad_state_is_refused_with_a_sentence() {
    // exp3: 13x7, tools key (0) and axe (1), objects door (0) and boulder (1).
    let w = load_world("exp3").unwrap();
    let ok = w.initial;
    assert_eq!(w.check_state(&ok), Ok(()));
    let edits: Vec<(&str, Edit<State>)> = vec![
        ("outside the 13x7 map", Box::new(|s| s.x = 13)),
        ("outside the 13x7 map", Box::new(|s| s.y = 200)),
        ("rock", Box::new(|s| (s.x, s.y) = (0, 0))),
        ("is no boulder state", Box::new(|s| s.objects[1] = 9999)),
        ("rock", Box::new(|s| s.objects[1] = 0)),
        ("is no door state", Box::new(|s| s.objects[0] = 3)),
        ("object slot 2", Box::new(|s| s.objects[2] = 1)),
        ("not a mode", Box::new(|s| s.mode = 200)),
        ("not a mode", Box::new(|s| s.mode = 4)),
        ("needs the key held", Box::new(|s| s.mode = 2)),
        ("needs a held tool", Box::new(|s| s.mode = 1)),
        ("beyond the world's 2", Box::new(|s| s.inventory = 0b100)),
        ("reserved", Box::new(|s| s.reserved = 1)),
    ];
    for (says, edit) in edits {
        let mut s = ok;
        edit(&mut s);
        let e = w.check_state(&s).expect_err(says);
        assert!(e.to_string().contains(says), "{says}: {e}");
        assert!(one_line(&e));
    }
    // A tree or wall is never open.
    let t = load_world("exp1-tree").unwrap();
    let mut s = t.initial;
    s.objects[0] = 1;
    assert!(t.check_state(&s).is_err());
    s.objects[0] = 2;
    assert_eq!(t.check_state(&s), Ok(()));
    // A destroyed boulder is a state.
    let mut s = ok;
    s.objects[1] = BOULDER_DESTROYED;
    assert_eq!(w.check_state(&s), Ok(()));
}

#[test]
fn each_kind_of_bad_record_is_refused_with_a_sentence() {
    // exp2: a destroy task of boulder (0) and door (1), max_steps 100.
    let w = load_world("exp2").unwrap();
    let good = EnvRecord::new(w.reset());
    assert!(check_record(&w, &good.to_bytes()).is_ok());
    let edits: Vec<(&str, Edit<EnvRecord>)> = vec![
        ("max_steps", Box::new(|r| r.episode.t = 100)),
        (
            "not all objects of the task",
            Box::new(|r| r.episode.rewarded = 0b100),
        ),
        ("task return", Box::new(|r| r.ext_return = f32::NAN)),
        ("task return", Box::new(|r| r.ext_return = -1.0)),
        ("task return", Box::new(|r| r.ext_return = 3.0)),
        (
            "intrinsic return",
            Box::new(|r| r.int_return = f32::INFINITY),
        ),
        (
            "not one of the world's",
            Box::new(|r| r.episode.state.mode = 77),
        ),
    ];
    for (says, edit) in edits {
        let mut r = good;
        edit(&mut r);
        let e = check_record(&w, &r.to_bytes()).expect_err(says);
        assert!(e.to_string().contains(says), "{says}: {e}");
        assert!(one_line(&e));
    }
    for (at, v) in [(52, 2), (53, 9), (54, 1), (55, 1)] {
        let mut b = good.to_bytes();
        b[at] = v;
        assert!(check_record(&w, &b).is_err(), "byte {at} = {v}");
    }
    assert!(check_record(&w, &good.to_bytes()[..ENV_BYTES - 1]).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A reachable state with random bytes written over it: refused with one line, or
    /// accepted and then stepped with every action and observed without a panic.
    #[test]
    fn whatever_check_state_accepts_the_dynamics_take(
        world_i in 0usize..5, seed in any::<u64>(), len in 0usize..200,
        edits in prop::collection::vec((0usize..38, any::<u8>()), 1..4),
    ) {
        let w = load_world(WORLDS[world_i]).unwrap();
        let s0 = *walk(&w, seed, len).last().unwrap();
        let mut b = s0.to_bytes();
        for (at, v) in edits {
            b[at] = v;
        }
        let s = State::from_bytes(&b);
        match w.check_state(&s) {
            Err(e) => prop_assert!(one_line(e)),
            Ok(()) => {
                let spec = w.obs_spec();
                let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
                w.observe(&s, &mut g, &mut f);
                prop_assert!(g.iter().all(|&x| (x as usize) < spec.glyphs));
                for a in 0..w.num_actions() as u8 {
                    let mut ep = fulcrum_world::Episode { state: s, t: 0, rewarded: 0 };
                    w.env_step(&mut ep, a);
                    w.observe_update(&s, &ep.state, &mut g.clone(), &mut f.clone());
                    prop_assert_eq!(w.check_state(&ep.state), Ok(()));
                }
            }
        }
    }

    /// Arbitrary record bytes: refused with one line or a record of the world.
    #[test]
    fn arbitrary_records_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..70)) {
        let w = load_world("exp3").unwrap();
        match check_record(&w, &bytes) {
            Err(e) => prop_assert!(one_line(e)),
            Ok(r) => prop_assert_eq!(w.check_state(&r.episode.state), Ok(())),
        }
    }

    /// One glyph byte of a real chunk: refused exactly when it is outside the world's
    /// glyphs, and the refusal names the glyph.
    #[test]
    fn a_glyph_is_refused_exactly_when_outside_the_alphabet(at in any::<usize>(), v in any::<u8>()) {
        let w = load_world("exp2").unwrap();
        let (h, l, mut p) = real_chunk(&w);
        prop_assert_eq!(check_chunk(&w, None, &l, true, &h, &p), Ok(()));
        let r = l.range(Section::Glyphs);
        p[r.start + at % r.len()] = v;
        let got = check_chunk(&w, None, &l, true, &h, &p);
        let alphabet = w.obs_spec().glyphs;
        prop_assert_eq!(got.is_ok(), (v as usize) < alphabet, "{:?}", got);
        if let Err(e) = got {
            prop_assert!(e.to_string().contains(&format!("glyph {v}")), "{}", e);
        }
    }
}

/// A chunk of 2 worlds x 4 steps of exp2 as an actor writes it (action 0 = north).
fn real_chunk(w: &World) -> (ChunkHeader, ChunkLayout, Vec<u8>) {
    let spec = w.obs_spec();
    let l = ChunkLayout {
        envs: 2,
        steps: 4,
        cells: spec.cells(),
        flags: spec.flags,
    };
    let h = ChunkHeader {
        envs: 2,
        steps: 4,
        cells: spec.cells() as u32,
        flags: spec.flags as u32,
        actions: w.num_actions() as u32,
        len: l.bytes() as u64,
        ..ChunkHeader::default()
    };
    let mut p = vec![0u8; l.bytes()];
    let (c, f) = (l.cells, l.flags);
    let (g0, f0) = (
        l.range(Section::Glyphs).start,
        l.range(Section::Flags).start,
    );
    for i in 0..l.n() {
        let (g, fl) = (g0 + i * c, f0 + i * f);
        let mut flags = vec![0u8; f];
        w.observe(&w.initial, &mut p[g..g + c], &mut flags);
        p[fl..fl + f].copy_from_slice(&flags);
    }
    let er = l.range(Section::EnvState).start;
    for e in 0..2 {
        p[er + e * ENV_BYTES..er + (e + 1) * ENV_BYTES]
            .copy_from_slice(&EnvRecord::new(w.reset()).to_bytes());
    }
    (h, l, p)
}

#[test]
fn each_kind_of_bad_chunk_is_refused_with_its_reason() {
    let w = load_world("exp2").unwrap();
    let (h, l, p) = real_chunk(&w);
    assert_eq!(check_chunk(&w, None, &l, true, &h, &p), Ok(()));
    let put = |p: &mut Vec<u8>, s: Section, i: usize, x: f32| {
        let r = l.range(s);
        p[r.start + 4 * i..r.start + 4 * i + 4].copy_from_slice(&x.to_le_bytes());
    };
    let er = l.range(Section::EnvState).start;
    let fr = l.range(Section::Flags).start;
    let cases: Vec<(&str, ChunkEdit)> = vec![
        (
            "glyph 200",
            Box::new(|p, _| p[l.range(Section::Glyphs).start + 5] = 200),
        ),
        ("not 0 or 1", Box::new(|p, _| p[fr + 1] = 2)),
        ("no mode, or more than one", Box::new(|p, _| p[fr + 4] = 0)),
        (
            "world 1's episode record",
            Box::new(|p, _| p[er + ENV_BYTES + 2] = 9),
        ),
        (
            "world 0's episode record",
            Box::new(|p, _| {
                // The boulder's slot (object 0: bytes 6..8 of the state) far off the map.
                p[er + 6] = 0x0f;
                p[er + 7] = 0x27;
            }),
        ),
        (
            "terminated and truncated",
            Box::new(|p, h| {
                p[l.range(Section::Terminated).start] = 1;
                p[l.range(Section::Truncated).start] = 1;
                h.episodes = 1;
            }),
        ),
        (
            "header",
            Box::new(|p, _| p[l.range(Section::Truncated).start] = 1),
        ),
        (
            "task reward",
            Box::new(|p, _| put(p, Section::ExtReward, 3, 2.5)),
        ),
        (
            "task reward",
            Box::new(|p, _| put(p, Section::ExtReward, 3, -1.0)),
        ),
        (
            "intrinsic reward",
            Box::new(|p, _| put(p, Section::IntReward, 1, 1e6)),
        ),
        (
            "log-probability",
            Box::new(|p, _| put(p, Section::Logprob, 0, 0.5)),
        ),
        (
            "log-probability",
            Box::new(|p, _| put(p, Section::Logprob, 0, -1e3)),
        ),
        ("value", Box::new(|p, _| put(p, Section::Value, 0, 1e20))),
        (
            "value",
            Box::new(|p, _| put(p, Section::LastValueInt, 1, -1e20)),
        ),
        (
            "action out of range",
            Box::new(|p, _| p[l.range(Section::Actions).start] = 9),
        ),
        // Apply (4) with nothing held: a masked actor never samples it.
        (
            "action 4 is one its mode does not allow",
            Box::new(|p, _| p[l.range(Section::Actions).start + 2] = 4),
        ),
    ];
    for (says, edit) in cases {
        let (mut hh, mut q) = (h, p.clone());
        edit(&mut q, &mut hh);
        let e: BadChunk = check_chunk(&w, None, &l, true, &hh, &q).expect_err(says);
        assert!(e.to_string().contains(says), "{says}: {e}");
        assert!(one_line(&e));
    }
}
