//! Every command line `fulcrum_run::argv` builds, parsed by this binary's own clap types:
//! what the child reads is what the parent meant.

use std::path::PathBuf;

use clap::Parser;
use fulcrum_run::argv::{self, BridgeConnect, BridgeListen, ChildKind, NewRun, TrainJob, Zenoh};
use fulcrum_run::child::ChildRequest;

use super::{Cli, Command};

fn parse(args: Vec<String>) -> Command {
    let argv = std::iter::once("fulcrum".to_string()).chain(args);
    match Cli::try_parse_from(argv) {
        Ok(cli) => cli.command,
        Err(e) => panic!("the built command line does not parse: {e}"),
    }
}

fn request() -> ChildRequest {
    ChildRequest {
        run: PathBuf::from("/runs/a b"),
        namespace: "t1f".into(),
        parent: 4242,
        index: 3,
        incarnation: 2,
        stop_after_updates: None,
        run_tag: None,
    }
}

#[test]
fn learner_and_actor_lines_give_back_their_requests() {
    let learner = ChildRequest {
        index: 0,
        incarnation: 0,
        stop_after_updates: Some(7),
        ..request()
    };
    match parse(argv::child(ChildKind::Learner, &learner)) {
        Command::Learner(c) => assert_eq!(c.request(), learner),
        other => panic!("{other:?}"),
    }
    let actor = ChildRequest {
        run_tag: Some("00abcdef01234567".into()),
        ..request()
    };
    match parse(argv::child(ChildKind::Actor, &actor)) {
        Command::Actor(c) => assert_eq!(c.request(), actor),
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_service_of_a_run_reads_its_directory() {
    match parse(argv::serve_run(&PathBuf::from("/runs/x"), "ns.1")) {
        Command::Serve(s) => {
            assert_eq!(s.run, Some(PathBuf::from("/runs/x")));
            assert_eq!(s.namespace, "ns.1");
            assert_eq!(s.world, None);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn both_bridges_get_every_setting() {
    let zenoh = Zenoh {
        session_timeout: 12.5,
        config: Some(PathBuf::from("/etc/z.json5")),
    };
    let listen = BridgeListen {
        addr: "0.0.0.0:7447".into(),
        run: PathBuf::from("/runs/r"),
        namespace: "t9".into(),
        parent: 77,
        zenoh: zenoh.clone(),
    };
    match parse(argv::bridge_listen(&listen)) {
        Command::Bridge(b) => {
            assert_eq!(b.listen.as_deref(), Some("0.0.0.0:7447"));
            assert_eq!(b.run, listen.run);
            assert_eq!(b.namespace.as_deref(), Some("t9"));
            assert_eq!(b.parent, Some(77));
            assert_eq!(b.zenoh.session_timeout, 12.5);
            assert_eq!(b.zenoh.zenoh_config, zenoh.config);
        }
        other => panic!("{other:?}"),
    }
    let connect = BridgeConnect {
        connect: "10.0.0.1:7447".into(),
        run: PathBuf::from("/home/h/run"),
        name: "hostb".into(),
        give_up: 30.0,
        parent: 88,
        world: Some("exp2".into()),
        run_id: Some("exp2-20261203-1".into()),
        zenoh: Zenoh {
            session_timeout: 5.0,
            config: None,
        },
    };
    match parse(argv::bridge_connect(&connect)) {
        Command::Bridge(b) => {
            assert_eq!(b.connect.as_deref(), Some("10.0.0.1:7447"));
            assert_eq!(b.run, connect.run);
            assert_eq!(b.name.as_deref(), Some("hostb"));
            assert_eq!(b.give_up, 30.0);
            assert_eq!(b.parent, Some(88));
            assert_eq!(b.world.as_deref(), Some("exp2"));
            assert_eq!(b.run_id.as_deref(), Some("exp2-20261203-1"));
            assert_eq!(b.zenoh.session_timeout, 5.0);
            assert_eq!(b.zenoh.zenoh_config, None);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_experiments_runs_parse_as_train_requests() {
    let job = TrainJob::New(NewRun {
        world: "exp1-tree-slip".into(),
        seed: Some(9),
        steps: Some(499_712),
        actors: Some(1),
        envs_per_actor: Some(8),
        checkpoint_every: Some(25),
        out: Some(PathBuf::from("/e/runs/additive/seed-9")),
        flags: vec![
            "--intrinsic".into(),
            "horizon-potential".into(),
            "--empowerment-model".into(),
            "deterministic".into(),
        ],
    });
    match parse(argv::train(&job)) {
        Command::Train(t) => {
            let r = t.request().unwrap();
            assert_eq!(r.world.as_deref(), Some("exp1-tree-slip"));
            assert_eq!((r.fixed.seed, r.resumable.steps), (Some(9), Some(499_712)));
            assert_eq!((r.fixed.actors, r.fixed.envs_per_actor), (Some(1), Some(8)));
            assert_eq!(r.resumable.checkpoint_every, Some(25));
            assert_eq!(r.out, Some(PathBuf::from("/e/runs/additive/seed-9")));
            assert_eq!(
                r.fixed.form(),
                Some(fulcrum_contracts::intrinsic::Intrinsic::HorizonPotential)
            );
            assert_eq!(
                r.fixed.empowerment_model,
                Some(fulcrum_contracts::config::EmpowermentModel::Deterministic)
            );
        }
        other => panic!("{other:?}"),
    }
    match parse(argv::train(&TrainJob::Resume(PathBuf::from("/e/runs/x")))) {
        Command::Train(t) => assert_eq!(t.resume, Some(PathBuf::from("/e/runs/x"))),
        other => panic!("{other:?}"),
    }
}

/// Every named arm of an experiment parses as a train request of the form it names.
#[test]
fn every_arm_is_train_flags() {
    use fulcrum_contracts::intrinsic::Intrinsic;
    for name in argv::ARMS.split(", ") {
        let flags = argv::arm_flags(name, "potential", Some(0.25)).unwrap();
        let job = TrainJob::New(NewRun {
            world: "room".into(),
            seed: None,
            steps: None,
            actors: Some(1),
            envs_per_actor: Some(8),
            checkpoint_every: None,
            out: None,
            flags,
        });
        let r = match parse(argv::train(&job)) {
            Command::Train(t) => t.request().unwrap_or_else(|e| panic!("{name}: {e}")),
            other => panic!("{other:?}"),
        };
        let want = match name {
            "baseline" | "baseline-unmasked" | "cleanrl" | "rllib" | "none" => Intrinsic::None,
            "empowerment" => Intrinsic::Potential,
            "paper" | "additive-fixed" => Intrinsic::Additive,
            "horizon-potential-deterministic" => Intrinsic::HorizonPotential,
            form => form.parse().unwrap(),
        };
        assert_eq!(r.fixed.form(), Some(want), "{name}");
    }
    assert_eq!(argv::arm_flags("bogus", "additive", None), None);
}

/// A run with train's defaults leaves every setting but its world, steps and directory
/// to train.
#[test]
fn a_default_run_names_only_world_steps_and_directory() {
    match parse(argv::train(&TrainJob::New(NewRun::new(
        "exp1-tree",
        16_384,
        &PathBuf::from("/b/t"),
    )))) {
        Command::Train(t) => {
            let r = t.request().unwrap();
            assert_eq!(r.world.as_deref(), Some("exp1-tree"));
            assert_eq!(r.resumable.steps, Some(16_384));
            assert_eq!(r.out, Some(PathBuf::from("/b/t")));
            assert_eq!(r.fixed, fulcrum_run::settings::Fixed::default());
            assert_eq!(r.resumable.checkpoint_every, None);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_benchs_helpers_parse() {
    let e = argv::ExperimentWorlds {
        worlds: "gen:20:seed=7".into(),
        seeds: 2,
        arms: vec!["baseline".into(), "horizon-potential".into()],
        steps: 999_424,
        out: PathBuf::from("/b/robust"),
    };
    match parse(argv::experiment_worlds(&e)) {
        Command::Experiment(x) => {
            assert_eq!(x.worlds.as_deref(), Some("gen:20:seed=7"));
            assert_eq!(x.seeds, 2);
            assert_eq!(x.arms, "baseline,horizon-potential");
            assert_eq!(x.steps, Some(999_424));
            assert_eq!(x.out, Some(PathBuf::from("/b/robust")));
        }
        other => panic!("{other:?}"),
    }
    match parse(argv::serve_world("exp2", "bench.1")) {
        Command::Serve(s) => {
            assert_eq!(s.world.as_deref(), Some("exp2"));
            assert_eq!(s.namespace, "bench.1");
            assert_eq!(s.run, None);
        }
        other => panic!("{other:?}"),
    }
    let c = argv::BenchClient {
        namespace: "bench.2".into(),
        world: "exp3".into(),
        seconds: 1.5,
        batch: 256,
    };
    match parse(argv::bench_client(&c)) {
        Command::BenchClient {
            namespace,
            world,
            seconds,
            batch,
        } => assert_eq!(
            (namespace, world, seconds, batch),
            ("bench.2".into(), "exp3".into(), 1.5, 256)
        ),
        other => panic!("{other:?}"),
    }
    match parse(argv::remote_peer("127.0.0.1:7447")) {
        Command::RemotePeer { listen } => assert_eq!(listen, "127.0.0.1:7447"),
        other => panic!("{other:?}"),
    }
    match parse(argv::pingpong(&PathBuf::from("/tmp/p s"))) {
        Command::PingPong { path } => assert_eq!(path, PathBuf::from("/tmp/p s")),
        other => panic!("{other:?}"),
    }
}

/// The old experiment files' default form parses as the additive bonus, and each of the
/// flags that name a form is one `train` reads as naming it.
#[test]
fn the_form_flags_name_a_form() {
    use fulcrum_contracts::intrinsic::Intrinsic;
    let form_of = |flags: Vec<String>| {
        let job = TrainJob::New(NewRun {
            flags,
            ..NewRun::new("room", 1024, &PathBuf::from("/f"))
        });
        match parse(argv::train(&job)) {
            Command::Train(t) => t.request().unwrap().fixed.form(),
            other => panic!("{other:?}"),
        }
    };
    assert_eq!(
        form_of(argv::additive_form().to_vec()),
        Some(Intrinsic::Additive)
    );
    assert_eq!(form_of(vec![]), None, "no flag names no form");
    for (flag, value) in argv::FORM_FLAGS.iter().zip(["first-visit", "", ""]) {
        let mut flags = vec![flag.to_string()];
        if !value.is_empty() {
            flags.push(value.to_string());
        }
        assert!(form_of(flags).is_some(), "{flag} names a form");
    }
}
