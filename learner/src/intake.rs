//! A chunk's way in: copied out of shared memory first, then checked whole
//! ([`fulcrum_contracts::chunk_check::check_chunk`]), then used. Checking the bytes in
//! shared memory and copying them afterwards would let the sender change them in
//! between; the copy is what the update trains on and what the checkpoint stores, so it
//! is what is checked.
//!
//! The tests below hold the promise that matters: whatever the check accepts, the real
//! update (a [`Batch`] built from the chunks, the fused PPO step) consumes without an
//! error or a panic, and leaves the network's weights finite.

use fulcrum_contracts::chunk_check::{check_chunk, BadChunk};
use fulcrum_contracts::traj::{ChunkHeader, ChunkLayout};
use fulcrum_world::{LayoutPool, Layouts, World};

use crate::batch::Chunk;

/// Copy a chunk's payload, then check the copy; the copy is the chunk the learner uses.
/// `action_mask`: whether the run masks actions per mode.
pub(crate) fn take_chunk(
    world: &World,
    family: Option<(&mut LayoutPool, Layouts)>,
    layout: &ChunkLayout,
    action_mask: bool,
    h: ChunkHeader,
    payload: &[u8],
) -> Result<Chunk, BadChunk> {
    let data = payload.to_vec();
    check_chunk(world, family, layout, action_mask, &h, &data)?;
    Ok(Chunk { h, data })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adam::Adam;
    use crate::batch::Batch;
    use crate::local::update;
    use crate::net::Net;
    use crate::running_std::RunningStd;
    use candle_core::Device;
    use fulcrum_contracts::chunk_check::{INT_REWARD_BOUND, LOGPROB_FLOOR, VALUE_BOUND};
    use fulcrum_contracts::config::{ChannelTool, HorizonMode, RunConfig};
    use fulcrum_contracts::intrinsic::Intrinsic;
    use fulcrum_contracts::ppo_config::PpoConfig;
    use fulcrum_contracts::traj::{put_f32, EnvRecord, Section, ENV_BYTES};
    use fulcrum_world::load_world;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const M: usize = 2;
    const T: usize = 8;

    fn cfg(world: &World, mask: bool, two_heads: bool, beta: f64) -> RunConfig {
        RunConfig {
            fulcrum_version: "0".into(),
            run_id: "r".into(),
            world: world.name.clone(),
            world_name: world.name.clone(),
            world_hash: "0".into(),
            seed: 1,
            total_steps: 10_000,
            actors: 2,
            envs_per_actor: M,
            steps_per_chunk: T,
            learner_threads: 1,
            hidden: 16,
            beta,
            empowerment: true,
            intrinsic: Intrinsic::Additive,
            horizon_mode: HorizonMode::Switch,
            potential_objects: fulcrum_contracts::config::PotentialObjects::Task,
            empowerment_model: fulcrum_contracts::config::EmpowermentModel::Exact,
            empowerment_from: None,
            tool: ChannelTool::Auto,
            selected_tool: None,
            objects: String::new(),
            horizon_unequipped: 2,
            horizon_equipped: 1,
            max_policy_lag: 0,
            remote: false,
            stall_timeout_s: 10.0,
            checkpoint_every: 10,
            eval_every: 0,
            eval_episodes: 10,
            eval_sample: false,
            action_mask: mask,
            view: fulcrum_world::View::Full,
            intrinsic_value_head: two_heads,
            gamma_int: 0.99,
            layouts: None,
            ppo: PpoConfig {
                minibatches: 2,
                epochs: 2,
                ..PpoConfig::default()
            },
        }
    }

    fn layout(world: &World) -> ChunkLayout {
        let spec = world.obs_spec();
        ChunkLayout {
            envs: M,
            steps: T,
            cells: spec.cells(),
            flags: spec.flags,
        }
    }

    /// A chunk as an actor writes it: M worlds stepped T times with random actions
    /// (auto-reset), their observations, rewards and records; plausible floats.
    fn valid_chunk(world: &World, seed: u64) -> (ChunkHeader, Vec<u8>) {
        let l = layout(world);
        let (c, f) = (l.cells, l.flags);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut p = vec![0u8; l.bytes()];
        let mut h = ChunkHeader {
            envs: M as u32,
            steps: T as u32,
            cells: c as u32,
            flags: f as u32,
            actions: world.num_actions() as u32,
            len: l.bytes() as u64,
            ..ChunkHeader::default()
        };
        let mut recs: Vec<EnvRecord> = (0..M).map(|_| EnvRecord::new(world.reset())).collect();
        // Some worlds start mid-episode, as in a chunk after the first.
        for r in &mut recs {
            for _ in 0..rng.random_range(0..30) {
                let a = rng.random_range(0..world.num_actions()) as u8;
                let out = world.env_step(&mut r.episode, a);
                r.ext_return += out.reward;
                if out.terminated || out.truncated {
                    *r = EnvRecord::new(world.reset());
                }
            }
        }
        let (g0, f0) = (
            l.range(Section::Glyphs).start,
            l.range(Section::Flags).start,
        );
        for t in 0..T {
            for (e, r) in recs.iter_mut().enumerate() {
                let i = t * M + e;
                let mut fl = vec![0u8; f];
                world.observe(
                    &r.episode.state,
                    &mut p[g0 + i * c..g0 + (i + 1) * c],
                    &mut fl,
                );
                p[f0 + i * f..f0 + (i + 1) * f].copy_from_slice(&fl);
                // An action the mode allows (what a masked actor samples).
                let allowed = fulcrum_world::mask::action_mask(&fl);
                let a = loop {
                    let a = rng.random_range(0..world.num_actions()) as u8;
                    if allowed >> a & 1 == 1 {
                        break a;
                    }
                };
                let out = world.env_step(&mut r.episode, a);
                r.ext_return += out.reward;
                p[l.range(Section::Actions).start + i] = a;
                p[l.range(Section::Terminated).start + i] = out.terminated as u8;
                p[l.range(Section::Truncated).start + i] = out.truncated as u8;
                put_f32(&mut p[l.range(Section::ExtReward)], i, out.reward);
                let lp = -(world.num_actions() as f32).ln() + rng.random_range(-1.0..0.5f32);
                put_f32(&mut p[l.range(Section::Logprob)], i, lp.min(0.0));
                for s in [Section::Value, Section::ValueInt] {
                    put_f32(&mut p[l.range(s)], i, rng.random_range(-2.0..2.0));
                }
                put_f32(
                    &mut p[l.range(Section::IntReward)],
                    i,
                    rng.random_range(0.0..3.0),
                );
                if out.truncated {
                    for s in [Section::TruncValue, Section::TruncValueInt] {
                        put_f32(&mut p[l.range(s)], i, rng.random_range(-2.0..2.0));
                    }
                }
                if out.terminated || out.truncated {
                    h.episodes += 1;
                    h.successes += out.terminated as u32;
                    *r = EnvRecord::new(world.reset());
                }
            }
        }
        let er = l.range(Section::EnvState).start;
        for (e, r) in recs.iter().enumerate() {
            p[er + e * ENV_BYTES..er + (e + 1) * ENV_BYTES].copy_from_slice(&r.to_bytes());
            for s in [Section::LastValue, Section::LastValueInt] {
                put_f32(&mut p[l.range(s)], e, rng.random_range(-2.0..2.0));
            }
        }
        (h, p)
    }

    /// The sections a mutation may hit.
    const SECTIONS: [Section; 15] = [
        Section::Glyphs,
        Section::Flags,
        Section::EnvState,
        Section::Actions,
        Section::Terminated,
        Section::Truncated,
        Section::ExtReward,
        Section::IntReward,
        Section::Logprob,
        Section::Value,
        Section::TruncValue,
        Section::LastValue,
        Section::ValueInt,
        Section::TruncValueInt,
        Section::LastValueInt,
    ];

    /// How a chunk is damaged: a random byte somewhere in a section, or a float
    /// section's slot (or the whole section) set to the extreme the check still accepts.
    #[derive(Debug, Clone)]
    enum Mutation {
        Byte(usize, usize, u8),
        Extreme(usize, usize, bool),
    }

    fn extreme(s: Section, world: &World, low: bool) -> f32 {
        match (s, low) {
            (Section::Logprob, true) => LOGPROB_FLOOR,
            (Section::Logprob, false) => 0.0,
            (Section::ExtReward, true) => 0.0,
            (Section::ExtReward, false) => world.max_episode_reward(),
            (Section::IntReward, true) => -INT_REWARD_BOUND,
            (Section::IntReward, false) => INT_REWARD_BOUND,
            (_, true) => -VALUE_BOUND,
            (_, false) => VALUE_BOUND,
        }
    }

    fn mutate(p: &mut [u8], l: &ChunkLayout, world: &World, m: &Mutation) {
        match *m {
            Mutation::Byte(s, at, v) => {
                let r = l.range(SECTIONS[s % SECTIONS.len()]);
                p[r.start + at % r.len()] = v;
            }
            Mutation::Extreme(s, at, low) => {
                // Float sections only (index 6 on); `at` past the slots fills them all.
                let s = SECTIONS[6 + s % (SECTIONS.len() - 6)];
                let x = extreme(s, world, low);
                let r = l.range(s);
                let slots = r.len() / 4;
                if at >= slots {
                    for i in 0..slots {
                        put_f32(&mut p[r.clone()], i, x);
                    }
                } else {
                    put_f32(&mut p[r], at, x);
                }
            }
        }
    }

    fn mutation() -> impl Strategy<Value = Mutation> {
        prop_oneof![
            3 => (0usize..15, any::<usize>(), any::<u8>()).prop_map(|(s, a, v)| Mutation::Byte(s, a, v)),
            1 => (0usize..9, 0usize..40, any::<bool>()).prop_map(|(s, a, l)| Mutation::Extreme(s, a, l)),
        ]
    }

    /// Train on `chunks` as the learner does: a Batch, then the fused update; the
    /// update must succeed and leave every weight finite.
    fn update_on(world: &World, cfg: &RunConfig, chunks: &[Chunk]) -> Result<(), String> {
        let l = layout(world);
        let net = Net::new(cfg.shape(world), 7, &Device::Cpu).map_err(|e| e.to_string())?;
        let mut adam = Adam::new(&net).map_err(|e| e.to_string())?;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut int_std = RunningStd::default();
        let batch = Batch::new(chunks, &l, cfg, 0, &mut int_std);
        update(
            &net,
            &mut adam,
            &cfg.ppo,
            2.5e-4,
            &mut rng,
            &batch.update_data(),
        )
        .map_err(|e| e.to_string())?;
        let w = net.flat().map_err(|e| e.to_string())?;
        match w.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(format!("weight {i} is {} after the update", w[i])),
            None => Ok(()),
        }
    }

    #[test]
    fn the_unmutated_chunks_are_accepted_and_train() {
        for name in ["exp2", "exp3", "room"] {
            let world = load_world(name).unwrap();
            let l = layout(&world);
            for seed in 0..20 {
                let (h, p) = valid_chunk(&world, seed);
                let c = take_chunk(&world, None, &l, true, h, &p)
                    .unwrap_or_else(|e| panic!("{name} seed {seed}: {e}"));
                update_on(&world, &cfg(&world, true, false, 0.1), &[c]).unwrap();
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Whatever the check accepts, the update consumes: no error, no panic, finite
        /// weights, masked or not, with one value head or two.
        #[test]
        fn whatever_the_check_accepts_the_update_consumes(
            world_i in 0usize..3,
            seed in any::<u64>(),
            muts in prop::collection::vec(mutation(), 1..6),
            mask in any::<bool>(),
            two_heads in any::<bool>(),
            beta in prop_oneof![Just(0.0), Just(0.0009), Just(1.0)],
        ) {
            let world = load_world(["exp2", "exp3", "room"][world_i]).unwrap();
            let l = layout(&world);
            let (h, mut p) = valid_chunk(&world, seed);
            for m in &muts {
                mutate(&mut p, &l, &world, m);
            }
            let (h2, p2) = valid_chunk(&world, seed ^ 1);
            if let Ok(c) = take_chunk(&world, None, &l, mask, h, &p) {
                let other = take_chunk(&world, None, &l, mask, h2, &p2).unwrap();
                let r = update_on(&world, &cfg(&world, mask, two_heads, beta), &[c, other]);
                prop_assert!(r.is_ok(), "{:?}: {:?}", muts, r);
            }
        }
    }
}
