//! World families through the binary: `world show FAMILY --layout N` prints a layout,
//! `--toml` writes it as an ordinary world file that every command takes, and bad
//! families and misplaced `--layout`s are one sentence with exit code 2.

use super::{bad_input, json};
use crate::util::{run as fulcrum, TempDir};

#[test]
fn a_layout_written_out_is_an_ordinary_world() {
    let out = fulcrum(&["world", "show", "toolbox", "--layout", "7", "--toml"]);
    assert!(out.status.success());
    let dir = TempDir::new("family-toml");
    let file = dir.join("toolbox-7.toml");
    std::fs::write(&file, &out.stdout).unwrap();
    let f = file.to_str().unwrap();
    // The written file is layout 7: the same map, the same content hash.
    let from_file = json(&["world", "show", f, "--json"]);
    let layout = json(&["world", "show", "toolbox", "--layout", "7", "--json"]);
    assert_eq!(from_file["map"], layout["map"]);
    assert_eq!(from_file["hash"], layout["hash"]);
    assert_eq!(layout["world"], "toolbox-7");
    assert_eq!(layout["family"]["layout"], 7);
    // One room, three tools in the family's order, one task object whose fitting tools
    // are those of the rule table.
    let tools: Vec<&str> = layout["tools"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["kind"].as_str().unwrap())
        .collect();
    assert_eq!(tools, ["axe", "pickaxe", "wand"]);
    let object = layout["objects"][0]["kind"].as_str().unwrap().to_string();
    let fit = match object.as_str() {
        "tree" => vec!["axe"],
        "wall" => vec!["pickaxe"],
        "boulder" => vec!["pickaxe", "wand"],
        other => panic!("toolbox drew a {other}"),
    };
    assert_eq!(layout["fitting_tools"], serde_json::json!(fit));
    // Every command takes the written layout: its matrix has the task object's column
    // and selects one of the family's tools for it.
    let m = json(&["empowerment", "matrix", f, "--json"]);
    assert_eq!(m["world"], "toolbox-7");
    assert_eq!(m["columns"], serde_json::json!([object]));
    let chosen = m["selection"][object.as_str()].as_str().unwrap();
    assert!(tools.contains(&chosen), "{m}");
}

#[test]
fn bad_families_and_layouts_are_one_sentence() {
    let dir = TempDir::new("family-bad");
    let file = dir.join("fam.toml");
    std::fs::write(
        &file,
        "name = \"f\"\n\n[family]\nwidth = 10\nheight = 8\ntools = [\"key\"]\nobjects = [\"tree\"]\n",
    )
    .unwrap();
    let f = file.to_str().unwrap();
    bad_input(
        &["world", "show", f, "--layout", "1"],
        "fam.toml:7:12: no tool of [family] tools destroys a tree",
    );
    bad_input(
        &["world", "show", "exp1-tree", "--layout", "3"],
        "--layout names a layout of a world family, and 'exp1-tree' is one world",
    );
    // A family trains on layouts; a world does not, and what does not fit a family is
    // refused before anything starts.
    bad_input(
        &["train", "exp1-tree", "--layouts", "4", "--steps", "1024"],
        "--layouts needs a world family, and 'exp1-tree' is one world (families: toolbox, two-rooms)",
    );
    bad_input(
        &["train", "toolbox", "--layouts", "0", "--steps", "1024"],
        "a run trains on 1 to 1099511627776 layouts (or all)",
    );
    bad_input(
        &["train", "toolbox", "--layouts", "some", "--steps", "1024"],
        "not a number of layouts or 'all'",
    );
    bad_input(
        &["train", "toolbox", "--objects", "tree", "--steps", "1024"],
        "--objects does not fit a world family: each layout of 'toolbox' names its own task object",
    );
    // Commands that take one world name the family's layouts instead.
    bad_input(
        &["empowerment", "matrix", "toolbox"],
        "toolbox: this is a world family (a layout per seed), not one world",
    );
}
