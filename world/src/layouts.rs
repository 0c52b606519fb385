//! Which layouts of a family a run trains on and is evaluated on, and the layouts an
//! actor keeps at hand.
//!
//! Training and held-out layouts come from disjoint seed ranges. A run trains on the
//! seeds `0..N` (`--layouts N`) or on any seed below [`HELD_OUT_START`] (`--layouts all`:
//! a fresh draw every episode, 2^40 layouts, so in practice none met twice); the held-out
//! layouts of an evaluation, `test:K`, are the seeds `HELD_OUT_START..HELD_OUT_START + K`,
//! which no run trains on. An episode's layout is drawn from one 64-bit random number
//! `r` of the actor's seeded generator: seed `floor(r * N / 2^64)` of `0..N` (uniform to
//! within N / 2^64), or `r mod 2^40` for `all`.

use std::collections::VecDeque;
use std::fmt;
use std::ops::Range;
use std::sync::Arc;

use crate::family::Family;
use crate::hash::FastMap;
use crate::parse::WorldError;
use crate::world::World;

/// The first held-out layout seed: every training seed is below it.
pub const HELD_OUT_START: u64 = 1 << 40;

/// The layouts a run trains on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layouts {
    /// The seeds `0..N`, each episode one of them uniformly.
    First(u64),
    /// Any seed below [`HELD_OUT_START`]: a fresh layout every episode.
    All,
}

impl Layouts {
    /// The training seeds.
    pub fn range(&self) -> Range<u64> {
        match *self {
            Layouts::First(n) => 0..n,
            Layouts::All => 0..HELD_OUT_START,
        }
    }

    /// How many parsed layouts a [`LayoutPool`] of a run on these layouts keeps: every
    /// training layout (up to 2^16), or `fresh` recent ones on every layout.
    pub fn pool_size(&self, fresh: usize) -> usize {
        match *self {
            Layouts::First(n) => n.min(1 << 16) as usize,
            Layouts::All => fresh,
        }
    }

    /// The layout seed drawn by the random number `r` (see the module docs).
    pub fn draw(&self, r: u64) -> u64 {
        match *self {
            Layouts::First(n) => ((r as u128 * n as u128) >> 64) as u64,
            Layouts::All => r & (HELD_OUT_START - 1),
        }
    }
}

impl fmt::Display for Layouts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Layouts::First(n) => write!(f, "{n}"),
            Layouts::All => f.write_str("all"),
        }
    }
}

impl std::str::FromStr for Layouts {
    type Err = String;

    /// `N` (1 to 2^40) or `all`.
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "all" {
            return Ok(Layouts::All);
        }
        match s.parse::<u64>() {
            Ok(n) if (1..=HELD_OUT_START).contains(&n) => Ok(Layouts::First(n)),
            Ok(_) => Err(format!(
                "a run trains on 1 to {HELD_OUT_START} layouts (or all)"
            )),
            Err(_) => Err("not a number of layouts or 'all'".to_string()),
        }
    }
}

impl serde::Serialize for Layouts {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for Layouts {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// The layouts an evaluation plays, one episode after another round them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EvalLayouts {
    /// Held-out seeds (`test:K` = `HELD_OUT_START..HELD_OUT_START + K`, or `test:A..B`).
    Test(Range<u64>),
    /// The first K training layouts of the run (`train:K`).
    Train(u64),
}

impl EvalLayouts {
    /// `test:K`, `test:A..B` or `train:K`.
    pub fn parse(s: &str) -> Result<EvalLayouts, String> {
        let count = |k: &str| match k.parse::<u64>() {
            Ok(n) if n >= 1 => Ok(n),
            _ => Err(format!(
                "--layouts {s}: '{k}' is not a number of layouts (1 or more)"
            )),
        };
        if let Some(k) = s.strip_prefix("train:") {
            return Ok(EvalLayouts::Train(count(k)?));
        }
        if let Some(rest) = s.strip_prefix("test:") {
            if let Some((a, b)) = rest.split_once("..") {
                let (a, b) = match (a.parse::<u64>(), b.parse::<u64>()) {
                    (Ok(a), Ok(b)) if a < b => (a, b),
                    _ => {
                        return Err(format!(
                            "--layouts {s}: '{rest}' is not a range of seeds A..B with A < B"
                        ))
                    }
                };
                return Ok(EvalLayouts::Test(a..b));
            }
            let k = count(rest)?;
            return Ok(EvalLayouts::Test(
                HELD_OUT_START..HELD_OUT_START.saturating_add(k),
            ));
        }
        Err(format!(
            "--layouts '{s}' is not test:K, test:A..B or train:K"
        ))
    }

    /// The seeds played, refused where held-out seeds fall among the run's training
    /// layouts `train`.
    pub fn seeds(&self, train: Layouts) -> Result<Range<u64>, String> {
        match self {
            EvalLayouts::Train(k) => {
                let r = train.range();
                Ok(0..(*k).min(r.end))
            }
            EvalLayouts::Test(r) => {
                let t = train.range();
                if r.start < t.end && t.start < r.end {
                    return Err(format!(
                        "held-out layouts {}..{} overlap the run's training layouts {}..{} (--layouts {train}): take seeds from {} on",
                        r.start, r.end, t.start, t.end, t.end
                    ));
                }
                Ok(r.clone())
            }
        }
    }

    /// How the layouts are named in `eval.csv` (`test:K`, `test:A..B`, `train:K`).
    pub fn label(&self) -> String {
        match self {
            EvalLayouts::Train(k) => format!("train:{k}"),
            EvalLayouts::Test(r) if r.start == HELD_OUT_START => {
                format!("test:{}", r.end - r.start)
            }
            EvalLayouts::Test(r) => format!("test:{}..{}", r.start, r.end),
        }
    }
}

/// A family's layouts as parsed worlds, kept by seed: all of them up to `keep`, then
/// the most recently made ones (a world still in use lives on in its `Arc`).
#[derive(Debug)]
pub struct LayoutPool {
    family: Family,
    worlds: FastMap<u64, Arc<World>>,
    order: VecDeque<u64>,
    keep: usize,
}

impl LayoutPool {
    /// A pool of `family`'s layouts that keeps up to `keep` of them.
    pub fn new(family: Family, keep: usize) -> LayoutPool {
        LayoutPool {
            family,
            worlds: FastMap::default(),
            order: VecDeque::new(),
            keep: keep.max(1),
        }
    }

    /// The family.
    pub fn family(&self) -> &Family {
        &self.family
    }

    /// Layout `seed`, made now if it is not kept.
    pub fn get(&mut self, seed: u64) -> Result<Arc<World>, WorldError> {
        if let Some(w) = self.worlds.get(&seed) {
            return Ok(w.clone());
        }
        let w = Arc::new(self.family.layout(seed)?);
        if self.order.len() >= self.keep {
            if let Some(old) = self.order.pop_front() {
                self.worlds.remove(&old);
            }
        }
        self.order.push_back(seed);
        self.worlds.insert(seed, w.clone());
        Ok(w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_cover_the_training_seeds_and_no_more() {
        let l = Layouts::First(3);
        assert_eq!(l.draw(0), 0);
        assert_eq!(l.draw(u64::MAX), 2);
        assert_eq!(l.draw(u64::MAX / 3), 0);
        assert_eq!(l.draw(u64::MAX / 3 + 1), 1);
        assert_eq!(Layouts::All.draw(u64::MAX), HELD_OUT_START - 1);
    }

    #[test]
    fn held_out_seeds_never_meet_training_seeds() {
        for train in [
            Layouts::First(16),
            Layouts::First(HELD_OUT_START),
            Layouts::All,
        ] {
            let r = EvalLayouts::parse("test:500")
                .unwrap()
                .seeds(train)
                .unwrap();
            assert_eq!(r, HELD_OUT_START..HELD_OUT_START + 500);
            assert!(r.start >= train.range().end);
        }
        let inside = EvalLayouts::parse("test:10..20").unwrap();
        let e = inside.seeds(Layouts::First(16)).unwrap_err();
        assert!(
            e.contains("overlap the run's training layouts 0..16"),
            "{e}"
        );
        assert!(inside.seeds(Layouts::All).is_err());
        assert_eq!(inside.seeds(Layouts::First(10)).unwrap(), 10..20);
        assert_eq!(
            EvalLayouts::parse("train:500")
                .unwrap()
                .seeds(Layouts::First(16)),
            Ok(0..16)
        );
    }

    #[test]
    fn bad_layouts_are_refused() {
        assert!("0".parse::<Layouts>().unwrap_err().contains("1 to"));
        assert!("x".parse::<Layouts>().is_err());
        assert_eq!("all".parse::<Layouts>(), Ok(Layouts::All));
        assert_eq!("256".parse::<Layouts>(), Ok(Layouts::First(256)));
        for bad in ["test:0", "test:5..5", "test:9..3", "held:4", "train:x"] {
            assert!(EvalLayouts::parse(bad).is_err(), "{bad}");
        }
    }
}
