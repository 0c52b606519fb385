//! Everything the learner checks in a trajectory chunk before it uses any of it.
//!
//! A chunk is bytes another process wrote; the learner trains on it, and stores its
//! episode records into the checkpoint that actors resume from. [`check_chunk`](crate::chunk_check::check_chunk) takes a
//! chunk the learner has already copied out of shared memory (so that the sender cannot
//! change it between the check and the use) and accepts it only when every section is
//! something an actor of this world could have written:
//!
//! | section | accepted |
//! |---|---|
//! | header and sizes, actions, done bytes, every float finite | [`ChunkLayout::validate`](crate::traj::ChunkLayout::validate) |
//! | actions, in a run with action masking | each allowed by its transition's flags ([`fulcrum_world::mask`]: an actor never samples another) |
//! | glyphs | each below the world's glyph count (`9 + tools`) |
//! | flags | each 0 or 1, exactly one mode flag set per transition |
//! | terminated, truncated | never both at one transition; the header's episode and success counts are their counts |
//! | env_state | each world's record one of the world's ([`check_record`](crate::valid::check_record)) |
//! | ext_reward | between 0 and the most one step of the task pays |
//! | int_reward | within [`INT_REWARD_BOUND`](crate::chunk_check::INT_REWARD_BOUND) |
//! | logprob | between [`LOGPROB_FLOOR`](crate::chunk_check::LOGPROB_FLOOR) and 0 |
//! | values (both heads, truncated, last) | within [`VALUE_BOUND`](crate::chunk_check::VALUE_BOUND) |
//!
//! The bounds are far outside anything a run produces and close enough that PPO's
//! arithmetic on an accepted chunk stays finite in f32: the policy ratio is
//! `exp(log pi - logprob) <= exp(-LOGPROB_FLOOR)`, and returns are sums of bounded
//! rewards and values. A property test in the learner (`intake.rs`) feeds the real
//! update with mutated chunks that this check accepts.

use crate::traj::{ChunkHeader, ChunkLayout, Section, ENV_BYTES};
use crate::valid::{check_record, InvalidRecord};
use fulcrum_world::mask::action_mask as action_mask_of;
use fulcrum_world::{LayoutPool, Layouts, World};

/// The lowest log-probability accepted for a taken action. An actor samples an action
/// with probability below `e^-50` (about 2e-22) essentially never; below it the ratio
/// `exp(log pi - logprob)` of PPO could overflow f32 in the update.
pub const LOGPROB_FLOOR: f32 = -50.0;
/// The largest magnitude accepted for a value estimate (1e9: returns of any run are
/// orders of magnitude smaller; squares and sums of values stay finite in f32).
pub const VALUE_BOUND: f32 = 1e9;
/// The largest magnitude accepted for an intrinsic reward b_t: every form pays less
/// (E is at most `h * log2 |A|` <= 64 * log2 21 < 282 bits; the horizon potential's
/// Phi, a sum over h <= 64 of E^h, stays below 9137; a count bonus is at most 1).
pub const INT_REWARD_BOUND: f32 = 1e4;

/// Why a chunk was refused: one line for the learner's log.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BadChunk {
    /// Shape, length, action range, done bytes, non-finite numbers, statistics.
    #[error("{0}")]
    Form(&'static str),
    /// One transition's data.
    #[error("transition {i}: {what}")]
    Transition {
        /// The transition (`t * M + e`).
        i: usize,
        /// What is wrong.
        what: String,
    },
    /// A world's episode record.
    #[error("world {e}'s episode record: {source}")]
    Record {
        /// The world of the chunk.
        e: usize,
        /// What is wrong.
        source: InvalidRecord,
    },
    /// The header's counts disagree with the payload.
    #[error("header: {0}")]
    Header(String),
}

fn f32_at(b: &[u8], i: usize) -> f32 {
    f32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
}

/// Check a chunk of `world` copied out of shared memory, for a run with action masking
/// on or off (see the module docs). On a world family (`family`: its layouts and those
/// the run trains on) each record is checked against its own layout, which must be one
/// the run trains on. Never panics, whatever the header and bytes.
pub fn check_chunk(
    world: &World,
    family: Option<(&mut LayoutPool, Layouts)>,
    layout: &ChunkLayout,
    action_mask: bool,
    h: &ChunkHeader,
    payload: &[u8],
) -> Result<(), BadChunk> {
    layout
        .validate(h, world.num_actions(), payload)
        .map_err(BadChunk::Form)?;
    let (c, f) = (layout.cells, layout.flags);
    let at = |i: usize, what: String| Err(BadChunk::Transition { i, what });
    let alphabet = world.obs_spec().glyphs;
    let glyphs = &payload[layout.range(Section::Glyphs)];
    if let Some(k) = glyphs.iter().position(|&g| g as usize >= alphabet) {
        return at(
            k / c.max(1),
            format!(
                "glyph {} at cell {} is not one of the world's {alphabet} glyphs",
                glyphs[k],
                k % c.max(1)
            ),
        );
    }
    let tools = world.tools.len();
    for (i, fl) in payload[layout.range(Section::Flags)]
        .chunks_exact(f.max(1))
        .enumerate()
    {
        if fl.iter().any(|&x| x > 1) || fl.len() != 2 * tools + 2 {
            return at(i, "a flag is not 0 or 1".to_string());
        }
        if fl[tools..].iter().filter(|&&x| x == 1).count() != 1 {
            return at(i, "the flags name no mode, or more than one".to_string());
        }
        let a = payload[layout.range(Section::Actions).start + i];
        if action_mask && action_mask_of(fl) >> a & 1 == 0 {
            return at(i, format!("action {a} is one its mode does not allow"));
        }
    }
    check_dones(layout, h, payload)?;
    let mut family = family;
    for (e, rec) in payload[layout.range(Section::EnvState)]
        .chunks_exact(ENV_BYTES)
        .enumerate()
    {
        let bad = |source| BadChunk::Record { e, source };
        match family.as_mut() {
            None => {
                let r = check_record(world, rec).map_err(bad)?;
                if r.layout != 0 {
                    return Err(bad(InvalidRecord::Field(format!(
                        "it names layout {}, and the run is on one world",
                        r.layout
                    ))));
                }
            }
            Some((pool, trains_on)) => {
                let seed = crate::traj::EnvRecord::from_bytes(rec).map_or(0, |r| r.layout);
                if !trains_on.range().contains(&seed) {
                    return Err(bad(InvalidRecord::Field(format!(
                        "its layout {seed} is not one the run trains on (--layouts {trains_on})"
                    ))));
                }
                let lw = pool
                    .get(seed)
                    .map_err(|why| bad(InvalidRecord::Field(format!("layout {seed}: {why}"))))?;
                check_record(&lw, rec).map_err(bad)?;
            }
        }
    }
    let max_r = world.max_episode_reward();
    let floats = |s: Section| &payload[layout.range(s)];
    let bounds: [(Section, f32, f32, &str); 9] = [
        (Section::ExtReward, 0.0, max_r, "task reward"),
        (
            Section::IntReward,
            -INT_REWARD_BOUND,
            INT_REWARD_BOUND,
            "intrinsic reward",
        ),
        (Section::Logprob, LOGPROB_FLOOR, 0.0, "log-probability"),
        (Section::Value, -VALUE_BOUND, VALUE_BOUND, "value"),
        (Section::TruncValue, -VALUE_BOUND, VALUE_BOUND, "value"),
        (Section::LastValue, -VALUE_BOUND, VALUE_BOUND, "value"),
        (Section::ValueInt, -VALUE_BOUND, VALUE_BOUND, "value"),
        (Section::TruncValueInt, -VALUE_BOUND, VALUE_BOUND, "value"),
        (Section::LastValueInt, -VALUE_BOUND, VALUE_BOUND, "value"),
    ];
    for (s, lo, hi, what) in bounds {
        let b = floats(s);
        for i in 0..b.len() / 4 {
            let x = f32_at(b, i);
            if !(lo..=hi).contains(&x) {
                return at(i, format!("{what} {x} is outside {lo}..={hi}"));
            }
        }
    }
    Ok(())
}

/// Terminated and truncated never both; the header counts the episodes that ended.
fn check_dones(layout: &ChunkLayout, h: &ChunkHeader, payload: &[u8]) -> Result<(), BadChunk> {
    let term = &payload[layout.range(Section::Terminated)];
    let trunc = &payload[layout.range(Section::Truncated)];
    if let Some(i) = term.iter().zip(trunc).position(|(&a, &b)| a == 1 && b == 1) {
        return Err(BadChunk::Transition {
            i,
            what: "terminated and truncated at once".to_string(),
        });
    }
    let ended = term.iter().zip(trunc).filter(|(&a, &b)| a + b == 1).count();
    let won = term.iter().filter(|&&a| a == 1).count();
    if h.episodes as usize != ended || h.successes as usize != won {
        return Err(BadChunk::Header(format!(
            "{} episodes and {} successes, but the done bytes end {ended} and terminate {won}",
            h.episodes, h.successes
        )));
    }
    if h.pickups > h.episodes || h.e_positive as usize > layout.n() {
        return Err(BadChunk::Header(
            "more pickups than episodes, or more positive E than transitions".to_string(),
        ));
    }
    Ok(())
}
