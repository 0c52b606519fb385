//! fulcrum-learner: the candle PPO learner. Not built yet: see the training issue.
