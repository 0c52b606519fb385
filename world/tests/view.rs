//! The partial view: a crop equals the full map's window around the agent, with rock
//! beyond the map, at random states of every built-in world and of generated ones; its
//! incremental update equals a fresh crop after every step; `full|crop:R` parses as
//! documented. The reference window is cut here, by plain indexing, from the full
//! observation ([`World::observe`]), which draws the map by another path than the
//! crop's per-cell lookups.

use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::view::MAX_CROP_RADIUS;
use fulcrum_world::{load_world, parse_world, View, World};
use rand::{Rng, SeedableRng};

/// Rock's glyph id (`docs/world.md`).
const ROCK: u8 = 0;
/// The agent's glyph id.
const AGENT: u8 = 3;

/// The built-in worlds and generated ones with boulders, doors and bolts; one generated
/// world smaller than a radius-4 window in both directions.
fn worlds() -> Vec<World> {
    let mut v: Vec<World> = fulcrum_world::builtin::NAMES
        .iter()
        .map(|n| load_world(n).unwrap())
        .collect();
    for (seed, (width, height, n)) in [(7, 6, 4), (12, 9, 4), (6, 5, 2), (5, 4, 1)]
        .into_iter()
        .enumerate()
    {
        let p = GenParams {
            width,
            height,
            tools: n,
            objects: n,
            rock: 0.1,
            seed: seed as u64,
        };
        let text = generate(&p).unwrap_or_else(|e| panic!("{width}x{height}: {e}"));
        v.push(parse_world(&text, "gen").unwrap());
    }
    v
}

/// The window of radius `r` cut from the full observation, rock outside the map.
fn reference_crop(w: &World, s: &fulcrum_world::State, r: usize) -> (Vec<u8>, Vec<u8>) {
    let spec = w.obs_spec();
    let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
    w.observe(s, &mut g, &mut f);
    let side = 2 * r + 1;
    let mut out = vec![ROCK; side * side];
    for i in 0..side {
        for j in 0..side {
            let (x, y) = (
                s.x as i64 + j as i64 - r as i64,
                s.y as i64 + i as i64 - r as i64,
            );
            if x >= 0 && y >= 0 && (x as usize) < w.width && (y as usize) < w.height {
                out[i * side + j] = g[y as usize * w.width + x as usize];
            }
        }
    }
    (out, f)
}

#[test]
fn a_crop_is_the_full_maps_window_with_rock_beyond_it() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let mut outside = 0usize;
    for w in &worlds() {
        for r in [1usize, 2, 4, 7] {
            let view = View::Crop(r as u8);
            let spec = view.spec(w);
            assert_eq!((spec.width, spec.height), (2 * r + 1, 2 * r + 1));
            assert_eq!(spec.flags, w.obs_spec().flags);
            let (mut g, mut f) = (vec![0xEEu8; spec.cells()], vec![0xEEu8; spec.flags]);
            let mut ep = w.reset();
            for step in 0..3_000 {
                let s = ep.state;
                view.observe(w, &s, &mut g, &mut f);
                let (want_g, want_f) = reference_crop(w, &s, r);
                assert_eq!(
                    (&g, &f),
                    (&want_g, &want_f),
                    "{} crop:{r} step {step}: {}",
                    w.name,
                    w.describe(&s)
                );
                // The agent sits at the centre.
                assert_eq!(g[r * (2 * r + 1) + r], AGENT);
                // Count window cells beyond the map: the test must see them.
                let (x, y) = (s.x as usize, s.y as usize);
                if x < r || y < r || x + r >= w.width || y + r >= w.height {
                    outside += 1;
                }
                let o = w.env_step(&mut ep, rng.random_range(0..w.num_actions() as u8));
                if o.terminated || o.truncated {
                    ep = w.reset();
                }
            }
        }
    }
    assert!(
        outside > 10_000,
        "only {outside} states with window cells beyond the map"
    );
}

/// A hand-drawn case: the agent in the corner of a 4 x 3 room sees rock above and to
/// the left of the map.
#[test]
fn a_crop_at_the_corner_by_hand() {
    let w = parse_world(
        "name = \"corner\"\nmap = \"\"\"\n@.a.\n....\n..T.\n\"\"\"\n[tools]\na = \"axe\"\n",
        "corner.toml",
    )
    .unwrap();
    let (mut g, mut f) = (vec![0u8; 9], vec![0u8; 4]);
    View::Crop(1).observe(&w, &w.initial, &mut g, &mut f);
    // Rows y = -1, 0, 1 and columns x = -1, 0, 1: rock outside; agent at (0, 0); floor.
    assert_eq!(g, vec![0, 0, 0, 0, 3, 1, 0, 1, 1]);
    // Radius 2 reaches the axe (tool 0, glyph 9) at (2, 0) and the tree (4) at (2, 2).
    let mut g = vec![0u8; 25];
    View::Crop(2).observe(&w, &w.initial, &mut g, &mut f);
    assert_eq!(
        g,
        vec![
            0, 0, 0, 0, 0, //
            0, 0, 0, 0, 0, //
            0, 0, 3, 1, 9, //
            0, 0, 1, 1, 1, //
            0, 0, 1, 1, 4, //
        ]
    );
    // Flags: not holding the axe, normal mode (the one-hot's first slot, at n = 1).
    assert_eq!(f, vec![0, 1, 0, 0]);
}

#[test]
fn a_crops_update_equals_a_fresh_crop() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    for w in &worlds() {
        for view in [View::Crop(1), View::Crop(3), View::Full] {
            let spec = view.spec(w);
            let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
            let (mut g2, mut f2) = (g.clone(), f.clone());
            let mut ep = w.reset();
            view.observe(w, &ep.state, &mut g, &mut f);
            for step in 0..10_000 {
                let prev = ep.state;
                let o = w.env_step(&mut ep, rng.random_range(0..w.num_actions() as u8));
                if o.terminated || o.truncated {
                    ep = w.reset();
                }
                view.update(w, &prev, &ep.state, &mut g, &mut f);
                view.observe(w, &ep.state, &mut g2, &mut f2);
                assert_eq!((&g, &f), (&g2, &f2), "{} {view} step {step}", w.name);
            }
        }
    }
}

#[test]
fn views_parse_as_documented() {
    assert_eq!("full".parse::<View>(), Ok(View::Full));
    assert_eq!("crop:4".parse::<View>(), Ok(View::Crop(4)));
    assert_eq!(
        format!("crop:{MAX_CROP_RADIUS}").parse::<View>(),
        Ok(View::Crop(63))
    );
    for bad in [
        "", "crop", "crop:", "crop:0", "crop:64", "crop:-1", "crop:x", "Full",
    ] {
        let e = bad.parse::<View>().unwrap_err();
        assert!(
            e.starts_with(&format!("unknown view '{bad}'")) && e.contains("crop:R"),
            "{bad}: {e}"
        );
    }
    assert_eq!(View::Crop(4).to_string(), "crop:4");
    assert_eq!(View::Full.to_string(), "full");
}
