//! The bridge's pure parts: addresses, host names, the hosts file, hello.

use crate::hello::*;
use crate::session::*;
use std::collections::BTreeMap;

#[test]
pub fn addresses_become_tcp_locators() {
    assert_eq!(locator("10.0.0.1:7447").unwrap(), "tcp/10.0.0.1:7447");
    assert_eq!(locator("hostb:80").unwrap(), "tcp/hostb:80");
    assert_eq!(locator("tcp/[::1]:7447").unwrap(), "tcp/[::1]:7447");
    for bad in ["10.0.0.1", ":7447", "h:port", "h:70000"] {
        let e = locator(bad).unwrap_err().to_string();
        assert!(e.contains(&format!("'{bad}' is not an address")), "{e}");
    }
}

#[test]
pub fn the_ready_line_carries_namespace_tag_and_host() {
    let j = Joined {
        local_ns: "t1f.h3".into(),
        run_tag: 0x00ab_cdef_0123_4567,
        host: 3,
    };
    assert_eq!(
        joined_line(&j),
        "fulcrum bridge: ready t1f.h3 00abcdef01234567 3"
    );
    let back = parse_joined(&joined_line(&j)).unwrap();
    assert_eq!(
        (back.local_ns.as_str(), back.run_tag, back.host),
        ("t1f.h3", j.run_tag, 3)
    );
    assert!(parse_joined("fulcrum bridge: ready, listening on tcp/x:1 for run t").is_none());
    assert_eq!(actor_id(3, 2), 3 * 1024 + 2);
}

#[test]
pub fn host_names_are_kept_across_joins_and_files() {
    let dir = std::env::temp_dir().join(format!("fulcrum-hosts-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("hosts.txt");
    let mut h = BTreeMap::new();
    h.insert("b".to_string(), (2, "vm2".to_string()));
    h.insert("a".to_string(), (1, "vm1".to_string()));
    write_hosts(&path, &h).unwrap();
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        "1 a vm1\n2 b vm2\n"
    );
    assert_eq!(read_hosts(&path), h);
    assert!(valid_host_name("node-7.lab_2") && !valid_host_name("a b") && !valid_host_name("x/y"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
pub fn only_loopback_may_listen_without_authentication() {
    for a in [
        "tcp/127.0.0.1:7447",
        "tcp/[::1]:7447",
        "127.0.0.2:1",
        "localhost:80",
    ] {
        assert!(is_loopback(a), "{a}");
    }
    for a in [
        "tcp/0.0.0.0:7447",
        "tcp/[::]:7447",
        "10.0.0.1:7447",
        "tcp/hostb:7447",
    ] {
        assert!(!is_loopback(a), "{a}");
    }
    let z = ZenohOptions {
        session_timeout: 2.0,
        zenoh_config: None,
    };
    let e = open_session(&z, "tcp/0.0.0.0:0", true, None)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "refusing to listen on tcp/0.0.0.0:0 without authentication: only a loopback address may be used without the run's secret"
    );
}

#[test]
pub fn a_run_keeps_one_owner_only_secret() {
    use crate::secret::Secret;
    use std::os::unix::fs::PermissionsExt;
    let dir = std::env::temp_dir().join(format!("fulcrum-secret-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (s, path) = Secret::for_run(&dir).unwrap();
    assert_eq!(s.expose().len(), 64);
    let meta = std::fs::metadata(&path).unwrap();
    assert_eq!(meta.permissions().mode() & 0o777, 0o600);
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text, format!("fulcrum:{}\n", s.expose()));
    // A resumed run finds the same secret; a copy of the file or the bare hex parse.
    assert_eq!(Secret::for_run(&dir).unwrap().0, s);
    assert_eq!(Secret::parse(s.expose(), "x").unwrap(), s);
    assert_eq!(format!("{s:?}"), "Secret(***)");
    let e = Secret::parse("fulcrum:xyz", "the file f")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("the file f does not hold a run secret"),
        "{e}"
    );
    // No temporary file is left beside it.
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
    assert_eq!(names.len(), 1);
    let _ = std::fs::remove_dir_all(&dir);
}
