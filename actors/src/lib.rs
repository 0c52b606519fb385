//! fulcrum-actors: actor processes (vectorised worlds, policy inference). Not built yet: see the training issue.
