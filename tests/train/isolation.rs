//! Nobody outside the run gets in: owner-only shared memory, no network socket, and
//! chunks of another run or world refused.

use super::*;

/// Every iceoryx2 file under `dir` (recursively) with group or other permission bits.
fn shared_files_not_owner_only(dir: &Path) -> (usize, Vec<String>) {
    use std::os::unix::fs::PermissionsExt;
    let (mut seen, mut wide) = (0, Vec::new());
    let Ok(rd) = std::fs::read_dir(dir) else {
        return (0, wide);
    };
    for e in rd.flatten() {
        let p = e.path();
        let Ok(m) = std::fs::symlink_metadata(&p) else {
            continue;
        };
        if m.is_dir() {
            let (s, w) = shared_files_not_owner_only(&p);
            seen += s;
            wide.extend(w);
        } else if p
            .file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with("iox2_"))
        {
            // iceoryx2 0.10 keeps one machine-wide node counter (4 bytes) readable and
            // writable by all on purpose (`enable_global_access` in its
            // global_management_segment.rs); it holds nothing of a run. FAULTS.md says so.
            if p.to_string_lossy().ends_with(".global_mgmt") {
                continue;
            }
            seen += 1;
            if m.permissions().mode() & 0o077 != 0 {
                wide.push(format!("{} {:o}", p.display(), m.permissions().mode()));
            }
        }
    }
    (seen, wide)
}

#[test]
fn shared_memory_of_a_run_is_owner_only() {
    let dir = TempDir::fresh("modes");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "64000", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    // While the run is live: its shared memory (/dev/shm), and iceoryx2's service,
    // node and event files (/tmp/iceoryx2).
    let (shm, wide_shm) = shared_files_not_owner_only(Path::new("/dev/shm"));
    let (tmp, wide_tmp) = shared_files_not_owner_only(Path::new("/tmp/iceoryx2"));
    assert!(
        shm >= 3 && tmp >= 3,
        "the run's files: {shm} in /dev/shm, {tmp} in /tmp/iceoryx2"
    );
    assert!(
        wide_shm.is_empty() && wide_tmp.is_empty(),
        "{wide_shm:?} {wide_tmp:?}"
    );
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
}

/// Socket inodes of a process's open files.
fn socket_inodes(pid: u32) -> Vec<String> {
    let mut v = Vec::new();
    if let Ok(rd) = std::fs::read_dir(format!("/proc/{pid}/fd")) {
        for e in rd.flatten() {
            if let Ok(t) = std::fs::read_link(e.path()) {
                let t = t.to_string_lossy().to_string();
                if let Some(i) = t.strip_prefix("socket:[") {
                    v.push(i.trim_end_matches(']').to_string());
                }
            }
        }
    }
    v
}

#[test]
fn nothing_of_a_run_uses_a_network_socket() {
    let dir = TempDir::fresh("net");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "2", "--steps", "128000", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    let mut pids = children_with(c.id(), "fulcrum");
    pids.push(c.id());
    assert!(
        pids.len() >= 4,
        "supervisor, service, learner, actors: {pids:?}"
    );
    let ours: Vec<String> = pids.iter().flat_map(|&p| socket_inodes(p)).collect();
    // Every TCP and UDP socket of the machine, v4 and v6: none is the run's.
    for table in ["tcp", "tcp6", "udp", "udp6"] {
        let text = std::fs::read_to_string(format!("/proc/net/{table}")).unwrap_or_default();
        for line in text.lines().skip(1) {
            let inode = line.split_whitespace().nth(9).unwrap_or("");
            assert!(
                !ours.iter().any(|i| i == inode),
                "a {table} socket of the run: {line}"
            );
        }
    }
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
}

#[test]
fn chunks_of_another_run_or_world_are_refused_and_counted() {
    use fulcrum_contracts::traj::{self, ChunkHeader, ChunkLayout, TrainNames};
    fulcrum_empowerment::service::quiet_ipc_logs();
    let dir = TempDir::fresh("foreign");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "64000", "--out", d][..],
            &["--no-empowerment"],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    // The run's services are named after its namespace (the learner's --namespace).
    // Publish well-formed chunks into the run's own trajectory service that claim
    // another run, and another world.
    let ns = {
        let t0 = Instant::now();
        loop {
            let found = pids_with(&["__learner", d]);
            if let Some(&p) = found.first() {
                let cmd = std::fs::read(format!("/proc/{p}/cmdline")).unwrap();
                let args: Vec<String> = String::from_utf8_lossy(&cmd)
                    .split('\0')
                    .map(str::to_string)
                    .collect();
                let i = args.iter().position(|a| a == "--namespace").unwrap();
                break args[i + 1].clone();
            }
            assert!(t0.elapsed() < Duration::from_secs(10), "no learner");
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let w = fulcrum_world::load_world("room").unwrap();
    let spec = w.obs_spec();
    let layout = ChunkLayout {
        envs: 4,
        steps: 32,
        cells: spec.cells(),
        flags: spec.flags,
    };
    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .unwrap();
    let names = TrainNames::new(&ns);
    let svc = traj::trajectory_service(&node, &names).unwrap();
    let publisher = svc
        .publisher_builder()
        .initial_max_slice_len(layout.bytes())
        .create()
        .unwrap();
    let good = ChunkHeader {
        run: traj::run_tag(&ns),
        world_hash: w.content_hash(),
        envs: 4,
        steps: 32,
        cells: spec.cells() as u32,
        flags: spec.flags as u32,
        actions: w.num_actions() as u32,
        len: layout.bytes() as u64,
        ..ChunkHeader::default()
    };
    for h in [
        ChunkHeader {
            run: good.run ^ 1,
            ..good
        },
        ChunkHeader {
            world_hash: good.world_hash ^ 1,
            ..good
        },
    ] {
        let mut s = publisher.loan_slice(layout.bytes()).unwrap();
        s.payload_mut().fill(0);
        *s.user_header_mut() = h;
        s.send().unwrap();
    }
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 500, 128);
    assert_eq!(
        rows.last().unwrap().dropped_chunks,
        2,
        "both foreign chunks refused"
    );
}
