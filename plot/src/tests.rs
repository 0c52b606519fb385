//! Pictures decoded back and checked pixel by pixel.

use std::io;
use std::path::{Path, PathBuf};

use crate::bands::{band_chart_svg, Band, BandChart};
use crate::curve::{
    format_steps, learning_curve_png, CurveLayout, CurvePoint, CURVE_HEIGHT, CURVE_WIDTH,
    EXTRINSIC_LINE, INTRINSIC_LINE, SUCCESS_LINE,
};
use crate::error::PlotError;
use crate::heatmap::{heatmap_png, Heatmap, HeatmapLayout};
use crate::style::{
    text_on, viridis, Rgb, CATEGORY_LINE, MAX_GRID_SIDE, NO_VALUE, VALUE_LINE, VIRIDIS,
};
use crate::text::font;
use crate::ticks::{decimals_for, format_value, nice_ticks};
use crate::trace::{trace_png, Trace, TraceLayout};
use std::fs;
use std::sync::atomic::{AtomicU64, Ordering};

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        static N: AtomicU64 = AtomicU64::new(0);
        let dir = std::env::temp_dir().join(format!(
            "fulcrum-plot-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

struct Image {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

impl Image {
    fn pixel(&self, x: i32, y: i32) -> Rgb {
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }
}

fn decode(path: &Path) -> Image {
    let bytes = fs::read(path).expect("read png");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    let decoder = png::Decoder::new(io::Cursor::new(bytes));
    let mut reader = decoder.read_info().expect("png header");
    let mut rgb = vec![0; reader.output_buffer_size().expect("buffer size")];
    let info = reader.next_frame(&mut rgb).expect("png frame");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    rgb.truncate(info.buffer_size());
    Image {
        width: info.width,
        height: info.height,
        rgb,
    }
}

fn no_temp_files(dir: &Path) -> bool {
    fs::read_dir(dir).expect("read dir").all(|e| {
        !e.expect("entry")
            .file_name()
            .to_string_lossy()
            .contains(".tmp-")
    })
}

type Grid<T> = Vec<Vec<T>>;
type Category<'a> = Option<(&'a str, &'a [String], &'a [usize])>;
type Case<'a> = (Vec<f64>, &'a [Option<String>], Category<'a>);

/// A 12x8 map with a rock border and a few values.
fn example_grid() -> (Grid<Option<f64>>, Grid<bool>, Grid<Option<char>>) {
    let (w, h) = (12, 8);
    let mut values = vec![vec![None; w]; h];
    let mut rock = vec![vec![false; w]; h];
    let mut glyphs = vec![vec![None; w]; h];
    for y in 0..h {
        for x in 0..w {
            if x == 0 || y == 0 || x == w - 1 || y == h - 1 || (x == 6 && y != 4) {
                rock[y][x] = true;
            } else if (x + y) % 7 != 3 {
                let v = [0.0, 1.0, 1.58, 2.0, 0.58][(x * 3 + y) % 5];
                values[y][x] = Some(v);
            }
        }
    }
    values[1][1] = Some(0.0);
    values[1][2] = Some(2.0);
    values[2][2] = Some(f64::NAN);
    glyphs[2][3] = Some('T');
    glyphs[3][8] = Some('a');
    glyphs[5][9] = Some('+');
    (values, rock, glyphs)
}

fn example_trace() -> (Vec<f64>, Vec<Option<String>>, Vec<String>, Vec<usize>) {
    let values = vec![0.0, 0.0, 0.58, 1.0, 1.0, 1.58, 2.0, 2.0, 1.0, 0.0, 0.0, 0.0];
    let names = [
        "right", "right", "pick up", "down", "down", "toggle", "right", "open", "left", "noop",
        "noop",
    ];
    let mut actions = vec![None];
    actions.extend(names.iter().map(|s| Some((*s).to_string())));
    let cats = vec!["closed".to_string(), "open".into(), "destroyed".into()];
    let door = vec![0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 2, 2];
    (values, actions, cats, door)
}

#[test]
fn heatmap_png_has_cells_colours_and_dark_rock() {
    let dir = TempDir::new("heatmap");
    let path = dir.0.join("heat.png");
    let (values, rock, glyphs) = example_grid();
    let h = Heatmap {
        title: "E^3 of the key per cell",
        values: &values,
        rock: &rock,
        glyphs: Some(&glyphs),
        unit: "bits",
    };
    heatmap_png(&path, &h).expect("heatmap");
    let img = decode(&path);
    let layout = HeatmapLayout::new(&path, &h, font().expect("font")).expect("layout");
    assert_eq!((img.width, img.height), (layout.width, layout.height));
    assert_eq!(layout.cell, 40);
    assert!(img.width >= 12 * 40 && img.height >= 8 * 40);
    // A pixel near the bottom-right corner of a cell: away from the printed text.
    let probe = |x: usize, y: usize| {
        let (x0, y0) = layout.cell_origin(x, y);
        img.pixel(x0 + layout.cell - 5, y0 + layout.cell - 5)
    };
    let low = probe(1, 1); // 0.0
    let high = probe(2, 1); // 2.0
    assert_ne!(low, high, "high and low cells share a colour");
    assert_eq!(low, viridis(0.0));
    assert_eq!(high, viridis(1.0));
    let luma = |c: Rgb| c.iter().map(|&v| u32::from(v)).sum::<u32>() / 3;
    for (x, y) in [(0, 0), (11, 7), (6, 2)] {
        let (x0, y0) = layout.cell_origin(x, y);
        let centre = img.pixel(x0 + layout.cell / 2, y0 + layout.cell / 2);
        assert!(
            luma(centre) < 60,
            "rock cell ({x},{y}) is not dark: {centre:?}"
        );
    }
    // NaN is drawn as "no value".
    assert_eq!(probe(2, 2), NO_VALUE);
    // The value is printed: the centre of a cell holds text-coloured pixels.
    let (x0, y0) = layout.cell_origin(2, 1);
    let text = text_on(viridis(1.0));
    let near = |a: Rgb, b: Rgb| (0..3).all(|k| a[k].abs_diff(b[k]) < 80);
    let inked = (x0..x0 + layout.cell)
        .flat_map(|x| (y0..y0 + layout.cell).map(move |y| (x, y)))
        .filter(|&(x, y)| near(img.pixel(x, y), text))
        .count();
    assert!(
        inked > 20,
        "no printed value in the cell ({inked} ink pixels)"
    );
    assert!(no_temp_files(&dir.0));
}

#[test]
fn trace_png_writes_a_picture_with_both_panels() {
    let dir = TempDir::new("trace");
    let path = dir.0.join("trace.png");
    let (values, actions, cats, door) = example_trace();
    let t = Trace {
        title: "E^3 key -> door along an episode",
        value_label: "E^3 key -> door (bits)",
        values: &values,
        actions: &actions,
        category: Some(("door", &cats, &door)),
    };
    trace_png(&path, &t).expect("trace");
    let img = decode(&path);
    let layout = TraceLayout::new(&path, &t, font().expect("font")).expect("layout");
    assert_eq!((img.width, img.height), (layout.width, layout.height));
    assert!(layout.category.is_some());
    assert_eq!(layout.actions, Some(false));
    assert!((layout.value.y_hi - 2.2).abs() < 1e-9);
    // The marker of step 6 (value 2) is drawn in the line colour.
    let (x, y) = (layout.px(6.0), layout.value.py(2.0));
    assert_eq!(img.pixel(x.round() as i32, y.round() as i32), VALUE_LINE);
    // The door is "destroyed" at the last step.
    let c = layout.category.expect("category panel");
    let (x, y) = (layout.px(11.0), c.py(2.0));
    assert_eq!(img.pixel(x.round() as i32, y.round() as i32), CATEGORY_LINE);
    assert!(no_temp_files(&dir.0));
}

#[test]
fn degenerate_inputs_do_not_panic() {
    let dir = TempDir::new("degenerate");
    let p = |name: &str| dir.0.join(name);
    // Empty grids are an error naming the file.
    let e = heatmap_png(
        &p("empty.png"),
        &Heatmap {
            title: "",
            values: &[],
            rock: &[],
            glyphs: None,
            unit: "",
        },
    )
    .expect_err("empty grid");
    assert!(matches!(e, PlotError::NoData { .. }));
    assert!(e.to_string().contains("empty.png"), "{e}");
    assert!(!p("empty.png").exists());
    let empty_rows = vec![Vec::new(), Vec::new()];
    assert!(heatmap_png(
        &p("rows.png"),
        &Heatmap {
            title: "t",
            values: &empty_rows,
            rock: &[],
            glyphs: None,
            unit: "bits",
        },
    )
    .is_err());

    // All equal, all NaN / infinite, ragged rows, extreme values, one cell.
    let grids: Vec<Vec<Vec<Option<f64>>>> = vec![
        vec![vec![Some(1.0); 3]; 2],
        vec![vec![Some(0.0); 3]; 2],
        vec![vec![Some(-2.0); 3]; 2],
        vec![vec![Some(f64::NAN), Some(f64::INFINITY), None]],
        vec![vec![Some(1.0)], vec![Some(2.0), None, Some(3.0)], vec![]],
        vec![vec![
            Some(f64::MAX),
            Some(-f64::MAX),
            Some(1e300),
            Some(-12345.678),
        ]],
        vec![vec![Some(1e-9), Some(2e-9)]],
        vec![vec![Some(0.5)]],
        vec![vec![None; 300]; 90],
    ];
    let rock = vec![vec![true, false], vec![false; 7]];
    let glyphs = vec![vec![Some('é'), Some('\u{1F600}'), Some('\0')]];
    for (i, g) in grids.iter().enumerate() {
        let path = p(&format!("grid{i}.png"));
        heatmap_png(
            &path,
            &Heatmap {
                title: "a title that is rather long for such a small grid, isn't it?",
                values: g,
                rock: &rock,
                glyphs: Some(&glyphs),
                unit: "",
            },
        )
        .expect("degenerate grid draws");
        decode(&path);
    }
    let huge = vec![vec![None; MAX_GRID_SIDE + 1]];
    assert!(matches!(
        heatmap_png(
            &p("huge.png"),
            &Heatmap {
                title: "",
                values: &huge,
                rock: &[],
                glyphs: None,
                unit: "",
            }
        ),
        Err(PlotError::TooLarge { .. })
    ));

    // Traces.
    let e = trace_png(
        &p("t0.png"),
        &Trace {
            title: "",
            value_label: "",
            values: &[],
            actions: &[],
            category: None,
        },
    )
    .expect_err("empty trace");
    assert!(matches!(e, PlotError::NoData { .. }));
    assert!(e.to_string().contains("t0.png"), "{e}");
    let names = vec!["a".to_string(), "b".to_string()];
    let no_names: Vec<String> = Vec::new();
    let long: Vec<f64> = (0..500).map(|i| f64::from(i).sin()).collect();
    let many_actions: Vec<Option<String>> = (0..40)
        .map(|i| Some(format!("action number {i}")))
        .collect();
    let cases: Vec<Case<'_>> = vec![
        (vec![1.0], &[], None),
        (vec![f64::NAN, f64::INFINITY, -f64::INFINITY], &[], None),
        (
            vec![-3.0, 2.0, f64::NAN, 4.0],
            &[],
            Some(("c", &names, &[0, 5, 1])),
        ),
        (vec![], &[], Some(("c", &names, &[0, 1, 1]))),
        (vec![1.0, 2.0], &[], Some(("c", &no_names, &[0, 1]))),
        (vec![f64::MAX, -f64::MAX], &[], None),
        (long, &[], Some(("door", &names, &[1; 500]))),
        (vec![0.5; 40], &many_actions, None),
    ];
    for (i, (values, actions, category)) in cases.iter().enumerate() {
        let path = p(&format!("trace{i}.png"));
        trace_png(
            &path,
            &Trace {
                title: "trace",
                value_label: "a y label much longer than the panel is high, so it has to shrink",
                values,
                actions,
                category: *category,
            },
        )
        .expect("degenerate trace draws");
        decode(&path);
    }
    assert!(no_temp_files(&dir.0));
}

#[test]
fn plot_errors_name_the_file() {
    let dir = TempDir::new("atomic");
    // Errors from the plot functions name the file.
    let e = heatmap_png(
        &dir.0.join("missing").join("h.png"),
        &Heatmap {
            title: "",
            values: &[vec![Some(1.0)]],
            rock: &[],
            glyphs: None,
            unit: "",
        },
    )
    .expect_err("missing dir");
    assert!(matches!(e, PlotError::Io { .. }));
    assert!(e.to_string().contains("h.png"), "{e}");
}

#[test]
fn helpers_are_sane() {
    assert_eq!(viridis(f64::NAN), VIRIDIS[0]);
    assert_eq!(viridis(2.0), VIRIDIS[8]);
    assert_eq!(format_value(1.0, 2), "1.00");
    assert_eq!(format_value(1.584_962_5, 2), "1.58");
    assert_eq!(format_value(-0.001, 2), "0.00");
    let (ticks, step) = nice_ticks(0.0, 2.2, 7);
    assert_eq!(step, 0.5);
    assert_eq!(ticks, vec![0.0, 0.5, 1.0, 1.5, 2.0]);
    assert_eq!(decimals_for(0.5), 1);
    assert_eq!(decimals_for(0.25), 2);
    assert_eq!(decimals_for(2.0), 0);
    assert!(nice_ticks(f64::NAN, 1.0, 5).0.is_empty());
}

fn synthetic_curve(n: usize) -> Vec<CurvePoint> {
    (0..n)
        .map(|i| {
            let t = i as f64 / n.max(2) as f64;
            CurvePoint {
                env_steps: (i as u64 + 1) * 40_960,
                success_rate: 1.0 / (1.0 + (-10.0 * (t - 0.5)).exp()),
                extrinsic_return: -0.4 + 1.3 * t + 0.05 * (i as f64).sin(),
                intrinsic_mean: 0.3 * (-3.0 * t).exp(),
            }
        })
        .collect()
}

#[test]
fn learning_curve_png_draws_both_panels() {
    let dir = TempDir::new("curve");
    let path = dir.0.join("curve.png");
    let points = synthetic_curve(50);
    learning_curve_png(&path, "PPO + object empowerment, key-door", &points).expect("curve");
    let img = decode(&path);
    assert_eq!((img.width, img.height), (CURVE_WIDTH, CURVE_HEIGHT));
    let first = img.pixel(0, 0);
    assert!(
        img.rgb.chunks_exact(3).any(|p| p != first),
        "the picture is a single colour"
    );
    let count = |c: Rgb| img.rgb.chunks_exact(3).filter(|p| *p == c).count();
    for (name, c) in [
        ("success", SUCCESS_LINE),
        ("extrinsic", EXTRINSIC_LINE),
        ("intrinsic", INTRINSIC_LINE),
    ] {
        assert!(
            count(c) > 200,
            "the {name} line is missing ({} px)",
            count(c)
        );
    }
    // The success line reaches the last point where the layout says.
    let layout = CurveLayout::new(&points, "t", font().expect("font"));
    let last = points[49];
    let (x, y) = (
        layout.px(last.env_steps as f64),
        layout.success.py(last.success_rate),
    );
    let (x, y) = (x.round() as i32, y.round() as i32);
    assert!(
        (-2..=2).any(|dx| (-2..=2).any(|dy| img.pixel(x + dx, y + dy) == SUCCESS_LINE)),
        "no success line at the last point ({x}, {y})"
    );
    assert!(layout.returns.y_lo <= -0.4 && layout.returns.y_hi >= 0.9);
    assert!(layout.x_hi >= 50.0 * 40_960.0);
    // Tick labels of steps are short.
    assert!(
        layout.x_ticks.iter().any(|(_, s)| s.ends_with('M')),
        "{:?}",
        layout.x_ticks
    );
    assert!(no_temp_files(&dir.0));
}

#[test]
fn learning_curve_edge_cases_do_not_panic() {
    let dir = TempDir::new("curve-edge");
    let nan = f64::NAN;
    let pt = |s: u64, a: f64, b: f64, c: f64| CurvePoint {
        env_steps: s,
        success_rate: a,
        extrinsic_return: b,
        intrinsic_mean: c,
    };
    let mut mixed = synthetic_curve(30);
    for (i, p) in mixed.iter_mut().enumerate() {
        if i % 4 == 1 {
            p.success_rate = nan;
            p.extrinsic_return = f64::INFINITY;
        }
    }
    mixed.reverse();
    let cases: Vec<Vec<CurvePoint>> = vec![
        vec![],
        vec![pt(0, 0.5, 1.0, 0.1)],
        vec![pt(12_345, nan, nan, nan)],
        vec![pt(0, nan, nan, nan), pt(10, nan, nan, nan)],
        vec![pt(100, 2.0, -5.0, -5.0), pt(100, -1.0, -5.0, -5.0)],
        vec![
            pt(u64::MAX, 1.0, f64::MAX, -f64::MAX),
            pt(0, 0.0, 0.0, 1e-300),
        ],
        vec![pt(5, 0.0, 0.0, 0.0); 3],
        mixed,
        synthetic_curve(5000),
    ];
    for (i, points) in cases.iter().enumerate() {
        let path = dir.0.join(format!("curve{i}.png"));
        learning_curve_png(&path, "a learning curve", points).expect("curve draws");
        let img = decode(&path);
        assert_eq!((img.width, img.height), (CURVE_WIDTH, CURVE_HEIGHT));
    }
    // A single point is drawn as a dot.
    let path = dir.0.join("dot.png");
    learning_curve_png(&path, "", &[pt(1000, 0.5, 1.0, 0.1)]).expect("dot");
    let img = decode(&path);
    let count = |c: Rgb| img.rgb.chunks_exact(3).filter(|p| *p == c).count();
    assert!(count(SUCCESS_LINE) > 10 && count(EXTRINSIC_LINE) > 10);
    // A long title shrinks rather than widening the picture.
    let path = dir.0.join("long.png");
    learning_curve_png(&path, &"a very long title ".repeat(20), &[]).expect("long");
    assert_eq!(decode(&path).width, CURVE_WIDTH);
    // Errors name the file.
    let e =
        learning_curve_png(&dir.0.join("missing").join("c.png"), "", &[]).expect_err("missing dir");
    assert!(e.to_string().contains("c.png"), "{e}");
    assert!(no_temp_files(&dir.0));
    assert_eq!(format_steps(0.0, 500.0, 5000.0), "0");
    assert_eq!(format_steps(2_500_000.0, 2_500_000.0, 1e7), "2.5M");
    assert_eq!(format_steps(20_000.0, 10_000.0, 1e5), "20k");
    assert_eq!(format_steps(750.0, 250.0, 1000.0), "750");
    // Step ticks are whole numbers even for a run with almost no steps.
    for n in [0, 1, 3] {
        let layout = CurveLayout::new(&[pt(n, 0.0, 0.0, 0.0)], "", font().expect("font"));
        assert!(
            layout
                .x_ticks
                .iter()
                .all(|(v, s)| v.fract() == 0.0 && !s.contains('.')),
            "{:?}",
            layout.x_ticks
        );
    }
}

/// Renders the example pictures for looking at:
/// `cargo test plot::tests::render_examples -- --ignored`.
#[test]
#[ignore = "writes /tmp/plot-heatmap.png, /tmp/plot-trace.png, /tmp/plot-curve.png and /tmp/plot-bands*.svg for inspection"]
fn render_examples() {
    let x: Vec<f64> = (0..=40).map(|i| f64::from(i) * 2500.0).collect();
    let arm = |name: &str, k: f64| Band {
        name: name.into(),
        mean: x.iter().map(|v| 1.0 - (-v / k).exp()).collect(),
        std: x.iter().map(|v| 0.1 * (-v / (2.0 * k)).exp()).collect(),
    };
    let names = [
        "baseline",
        "additive",
        "potential",
        "horizon-potential",
        "first-visit",
        "count",
        "cleanrl",
        "rllib",
        "baseline-unmasked",
    ];
    let bands: Vec<Band> = names
        .iter()
        .enumerate()
        .map(|(i, n)| arm(n, 5000.0 * (i + 1) as f64))
        .collect();
    let chart = BandChart::over_steps(
        "success rate over seeds".into(),
        "success rate".into(),
        x.clone(),
        bands,
    );
    band_chart_svg(Path::new("/tmp/plot-bands.svg"), &chart).expect("bands");
    let log = BandChart {
        x_log: true,
        y_log: true,
        ..chart
    };
    band_chart_svg(Path::new("/tmp/plot-bands-log.svg"), &log).expect("log bands");
    let (values, rock, glyphs) = example_grid();
    heatmap_png(
        Path::new("/tmp/plot-heatmap.png"),
        &Heatmap {
            title: "E^3 of the key, per agent cell",
            values: &values,
            rock: &rock,
            glyphs: Some(&glyphs),
            unit: "bits",
        },
    )
    .expect("heatmap");
    let (values, actions, cats, door) = example_trace();
    trace_png(
        Path::new("/tmp/plot-trace.png"),
        &Trace {
            title: "E^3 key -> door along an episode",
            value_label: "E^3 key -> door (bits)",
            values: &values,
            actions: &actions,
            category: Some(("door", &cats, &door)),
        },
    )
    .expect("trace");
    learning_curve_png(
        Path::new("/tmp/plot-curve.png"),
        "PPO + object empowerment on key-door",
        &synthetic_curve(50),
    )
    .expect("curve");
}
