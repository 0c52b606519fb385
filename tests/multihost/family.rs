//! A run on a world family across hosts: the remote actors play the family's layouts,
//! the learner's side checks their chunks against each row's own layout, and their
//! lookups carry each state's layout over zenoh to the run's service.

use std::time::Duration;

use super::{host_rows, loopback};

#[test]
fn an_actor_host_trains_on_a_family_and_its_lookups_name_their_layouts() {
    let mut lb = loopback("family", "toolbox --layouts 8 --actors 1 --steps 204800");
    let mut host = lb.host("far", "--actors 1 --world toolbox");
    let status = lb.learner.finish(Duration::from_secs(240));
    assert!(status.success(), "{}", lb.learner.text());
    let hs = host.finish(Duration::from_secs(30));
    assert!(hs.success(), "{}", host.text());
    assert!(host.text().contains("the run is over"), "{}", host.text());

    // The far actor took part: 8 layouts over 4 worlds, so its states are of layouts
    // other than 0, which the learner's side would refuse checked against layout 0 and
    // the service would not find were the layouts lost on the way.
    let remote = host_rows(&lb.dir)
        .into_iter()
        .filter(|r| r.name == "far")
        .count();
    assert!(
        remote >= 20,
        "the remote actor took part in {remote} updates"
    );
    let learner_text = lb.learner.text();
    let stopped = learner_text
        .lines()
        .find(|l| l.starts_with("fulcrum bridge: stopped:"))
        .unwrap_or_else(|| panic!("no bridge line:\n{learner_text}"));
    assert!(
        stopped.contains("refused: 0 chunks, 0 lookups"),
        "{stopped}"
    );
    let lookups: u64 = stopped
        .split(';')
        .find_map(|p| p.trim().strip_suffix(" unanswered"))
        .and_then(|p| p.split(" lookups, ").next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no lookup count in: {stopped}"));
    assert!(lookups >= 100, "{stopped}");
    assert!(
        !host.text().contains("not in the world's state space"),
        "{}",
        host.text()
    );
    // The host keeps the family as the run's world file.
    let world = std::fs::read_to_string(lb.far.join("world.toml")).unwrap();
    assert!(world.contains("[family]"), "{world}");
    let _ = std::fs::remove_dir_all(&lb.far);
}
