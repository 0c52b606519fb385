//! The intrinsic reward forms on hand-made transitions; expected values are worked out
//! by hand in the comments (gamma = 0.99).

use fulcrum_contracts::intrinsic::{bonus, Intrinsic, Shaping};

fn shaping(form: Intrinsic, phi_reset: f32) -> Shaping {
    Shaping {
        form,
        gamma: G,
        phi_reset,
        inventory_reset: 0,
    }
}

/// `chunk` with every inventory 0 (no pick-ups).
fn chunk(sh: Shaping, next: &[f32], term: &[u8], trunc: &[u8], phi: &mut [f32], out: &mut [f32]) {
    let m = phi.len();
    let (mut inv, mut paid) = (vec![0u16; m], vec![false; m]);
    sh.chunk(
        next,
        &vec![0; next.len()],
        term,
        trunc,
        phi,
        &mut inv,
        &mut paid,
        out,
    );
}

const G: f32 = 0.99;

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() < 1e-6
}

#[test]
fn each_form_on_single_transitions() {
    // s_t with E = 1 -> s_{t+1} with E = 1 (standing on a beacon).
    assert_eq!(bonus(Intrinsic::Additive, G, 1.0, 1.0, false), 1.0);
    assert!(close(
        bonus(Intrinsic::Potential, G, 1.0, 1.0, false),
        -0.01
    ));
    // 0 -> 1 (reaching the beacon): the potential pays 0.99.
    assert!(close(bonus(Intrinsic::Potential, G, 0.0, 1.0, false), 0.99));
    // 1 -> terminal: the terminal potential is 0 whatever E the service gives it.
    assert!(close(bonus(Intrinsic::Potential, G, 1.0, 2.0, true), -1.0));
    assert_eq!(bonus(Intrinsic::Additive, G, 1.0, 2.0, true), 2.0);
    // Counts 1, 4, 16 -> 1, 1/2, 1/4.
    for (n, b) in [(1.0, 1.0), (4.0, 0.5), (16.0, 0.25)] {
        assert!(close(bonus(Intrinsic::Count, G, 0.0, n, false), b));
    }
    assert_eq!(bonus(Intrinsic::None, G, 1.0, 1.0, false), 0.0);
}

#[test]
fn a_chunk_with_a_terminal_and_a_truncated_step() {
    // Two worlds, five steps, time-major (i = 2t + e). World 0: E(s0) = 0.5 (the reset
    // state) -> 1 -> 1 -> terminal (service says 0.7), reset -> 1 truncated, reset -> 0.
    // World 1: E = 0 throughout, no episode end.
    let next = [1.0, 0.0, 1.0, 0.0, 0.7, 0.0, 1.0, 0.0, 0.0, 0.0];
    let term = [0, 0, 0, 0, 1, 0, 0, 0, 0, 0];
    let trunc = [0, 0, 0, 0, 0, 0, 1, 0, 0, 0];
    let mut out = [0.0f32; 10];

    let mut phi = [0.5, 0.0];
    chunk(
        shaping(Intrinsic::Potential, 0.5),
        &next,
        &term,
        &trunc,
        &mut phi,
        &mut out,
    );
    // World 0: 0.99*1 - 0.5 = 0.49; 0.99*1 - 1 = -0.01; terminal: 0 - 1 = -1;
    // after the reset: 0.99*1 - 0.5 = 0.49 (truncated keeps the state's own potential);
    // after the next reset: 0.99*0 - 0.5 = -0.5. World 1: 0 everywhere.
    let want0 = [0.49, -0.01, -1.0, 0.49, -0.5];
    for (t, w) in want0.iter().enumerate() {
        assert!(close(out[2 * t], *w), "t = {t}: {} != {w}", out[2 * t]);
        assert_eq!(out[2 * t + 1], 0.0);
    }
    // World 0's potential now: E of its current state, 0 (the last s_{t+1}).
    assert_eq!(phi, [0.0, 0.0]);
    // The terminated episode's discounted shaping telescopes to -E(s0) = -0.5.
    let sum = want0[0] + G * want0[1] + G * G * want0[2];
    assert!(close(sum, -0.5), "{sum}");

    let mut phi = [0.5, 0.0];
    chunk(
        shaping(Intrinsic::Additive, 0.5),
        &next,
        &term,
        &trunc,
        &mut phi,
        &mut out,
    );
    assert_eq!(out, next);

    let counts = [1.0, 1.0, 4.0, 2.0, 16.0, 3.0, 1.0, 4.0, 25.0, 5.0];
    let mut phi = [0.0, 0.0];
    chunk(
        shaping(Intrinsic::Count, 0.0),
        &counts,
        &term,
        &trunc,
        &mut phi,
        &mut out,
    );
    for (o, n) in out.iter().zip(counts) {
        assert!(close(*o, 1.0 / f32::sqrt(n)));
    }
}

#[test]
fn forms_parse_and_print() {
    for f in Intrinsic::ALL {
        assert_eq!(f.name().parse::<Intrinsic>().unwrap(), f);
    }
    let e = "bonus".parse::<Intrinsic>().unwrap_err();
    assert!(e.contains("'bonus'") && e.contains("potential"), "{e}");
}

#[test]
fn horizon_potential_is_potential_shaping_of_phi() {
    // Phi counts steps: 3 -> 4 pays 0.99 * 4 - 3 = 0.96; 4 -> terminal pays -4.
    assert!(close(
        bonus(Intrinsic::HorizonPotential, G, 3.0, 4.0, false),
        0.96
    ));
    assert!(close(
        bonus(Intrinsic::HorizonPotential, G, 4.0, 9.0, true),
        -4.0
    ));
    assert!(Intrinsic::HorizonPotential.horizon_sum());
    assert!(!Intrinsic::Potential.horizon_sum());
}

#[test]
fn first_visit_pays_once_per_inventory_per_episode() {
    // One world, eight steps. E of s_{t+1}: 0, 1 (beacon next to the axe), 1 (still
    // there), 0 (picked the axe up: inventory 1), 2 (next to the tree, axe held), 2,
    // terminal at 1; then the new episode (inventory 0 again) reaches E = 1.
    let next = [0.0, 1.0, 1.0, 0.0, 2.0, 2.0, 1.0, 1.0];
    let inv = [0u16, 0, 0, 1, 1, 1, 1, 0];
    let term = [0, 0, 0, 0, 0, 0, 1, 0];
    let trunc = [0u8; 8];
    let sh = Shaping {
        form: Intrinsic::FirstVisit,
        gamma: G,
        phi_reset: 0.0,
        inventory_reset: 0,
    };
    let (mut phi, mut cur, mut paid) = ([0.0f32], [0u16], [false]);
    let mut out = [0.0f32; 8];
    sh.chunk(
        &next, &inv, &term, &trunc, &mut phi, &mut cur, &mut paid, &mut out,
    );
    // Paid: the first E > 0 without the axe (1), the first with it (2), and the first of
    // the next episode (1). Standing on the beacon earns nothing more.
    assert_eq!(out, [0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0, 1.0]);
    assert_eq!((cur, paid), ([0], [true]));
    // Split in two chunks, the carried flags give the same rewards.
    let (mut phi, mut cur, mut paid) = ([0.0f32], [0u16], [false]);
    let mut a = [0.0f32; 3];
    let mut b = [0.0f32; 5];
    sh.chunk(
        &next[..3],
        &inv[..3],
        &term[..3],
        &trunc[..3],
        &mut phi,
        &mut cur,
        &mut paid,
        &mut a,
    );
    sh.chunk(
        &next[3..],
        &inv[3..],
        &term[3..],
        &trunc[3..],
        &mut phi,
        &mut cur,
        &mut paid,
        &mut b,
    );
    assert_eq!([&a[..], &b[..]].concat(), out.to_vec());
}

#[test]
fn default_betas_by_form() {
    // horizon-potential: 0.4 / max Phi; a two-state object at H = 8 (max Phi = 8) gives
    // 0.05; no potential anywhere falls back to 0.05.
    assert_eq!(Intrinsic::HorizonPotential.default_beta(0.0009, 8.0), 0.05);
    assert_eq!(Intrinsic::HorizonPotential.default_beta(0.0009, 20.0), 0.02);
    assert_eq!(Intrinsic::HorizonPotential.default_beta(0.0009, 0.0), 0.05);
    // The others ignore the potential: the world's beta, or their own.
    assert_eq!(Intrinsic::Additive.default_beta(0.0009, 8.0), 0.0009);
    assert_eq!(Intrinsic::Potential.default_beta(0.0009, 8.0), 0.0009);
    assert_eq!(Intrinsic::Count.default_beta(0.0009, 8.0), 0.0009);
    assert_eq!(Intrinsic::FirstVisit.default_beta(0.0009, 8.0), 0.1);
    assert_eq!(Intrinsic::None.default_beta(0.0009, 8.0), 0.0);
}
