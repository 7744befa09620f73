//! `musculo report`: the pages hold every plot, and in a real browser (headless Chromium) every
//! plot draws content — `report --png` renders each `<figure class="plot">` on its own to PNG,
//! and each must show at least a few hundred pixels in the plots' data colours (not the black,
//! grey and white of axes, text and background).
//!
//! Chromium is `MUSCULO_CHROMIUM`, else `chromium` or `chromium-browser` on the PATH; without
//! it the browser test reports "skipped: chromium not found", unless `MUSCULO_REQUIRE_CHROMIUM=1`
//! (as `.ci/run` sets after installing Debian's package), which makes it a failure.

mod common;

use common::musculo_cli;
use std::path::{Path, PathBuf};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("musculo-report-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The demo clips augmented (with measured-load-free estimates) and their report.
fn demo_report(dir: &Path) -> PathBuf {
    let (aug, pages) = (dir.join("aug"), dir.join("pages"));
    let (ok, _, err) = musculo_cli("augment --demo --report --out {}", &[&aug]);
    assert!(ok, "{err}");
    assert!(aug.join("report/index.html").is_file(), "augment --report");
    let (ok, out, err) = musculo_cli("report {} --out {}", &[&aug, &pages]);
    assert!(ok, "{err}");
    assert!(out.contains("4 page(s)"), "{out}");
    pages
}

use musculo::report::figures as plots;

#[test]
fn pages_hold_every_plot() {
    let dir = temp_dir("plots");
    let pages = demo_report(&dir);
    let squat = std::fs::read_to_string(pages.join("squat.html")).unwrap();
    let ids: Vec<String> = plots(&squat).into_iter().map(|(id, _)| id).collect();
    assert_eq!(
        ids,
        [
            "joint_angles",
            "joint_torques",
            "ground_reaction",
            "centre_of_pressure",
            "contact_timeline",
            "activations",
            "reserve_share",
            "ik_marker_error"
        ]
    );
    // self-contained: no script and nothing fetched
    for forbidden in ["<script", "src=\"http", "href=\"http", "url("] {
        assert!(!squat.contains(forbidden), "{forbidden}");
    }
    let index = std::fs::read_to_string(pages.join("index.html")).unwrap();
    for clip in ["march", "squat", "reach"] {
        assert!(
            index.contains(&format!("<a href=\"{clip}.html\">")),
            "{clip}"
        );
    }
    assert!(plots(&index).len() >= 5);
    let _ = std::fs::remove_dir_all(dir);
}

fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("MUSCULO_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .flat_map(|d| [d.join("chromium"), d.join("chromium-browser")])
        .find(|p| p.is_file())
}

/// Pixels of a PNG whose colour is saturated (max − min channel ≥ 40): drawn data.
fn coloured_pixels(png_path: &Path) -> usize {
    let decoder = png::Decoder::new(std::fs::File::open(png_path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    assert!(channels >= 3, "{:?}", info.color_type);
    buf[..info.buffer_size()]
        .chunks(channels)
        .filter(|p| {
            let (hi, lo) = (p[0].max(p[1]).max(p[2]), p[0].min(p[1]).min(p[2]));
            hi - lo >= 40
        })
        .count()
}

#[test]
fn every_plot_draws_content_in_a_real_browser() {
    let Some(browser) = chromium() else {
        if std::env::var("MUSCULO_REQUIRE_CHROMIUM").is_ok_and(|v| v == "1") {
            panic!("chromium not found (MUSCULO_REQUIRE_CHROMIUM=1)");
        }
        eprintln!("skipped: chromium not found");
        return;
    };
    let dir = temp_dir("browser");
    let pages = demo_report(&dir);
    // the product's own PNG path: `report --png`, every figure through the browser
    let png_dir = dir.join("png");
    let (ok, out, err) = musculo_cli(
        "report {} --out {} --png --chromium {}",
        &[&dir.join("aug"), &png_dir, &browser],
    );
    assert!(ok, "{err}");
    assert!(out.contains("figure(s) written as PNG"), "{out}");
    let mut checked = 0;
    for page in ["squat", "index"] {
        let html = std::fs::read_to_string(pages.join(format!("{page}.html"))).unwrap();
        for (id, svg) in plots(&html) {
            let png = png_dir.join(format!("{page}.{id}.png"));
            assert!(png.is_file(), "{}", png.display());
            let drawn = coloured_pixels(&png);
            let (w, h) = musculo::report::svg_size(&svg).unwrap();
            println!("{page} {id}: {w}×{h}, {drawn} pixels of drawn data");
            assert!(drawn >= 300, "{page} {id}: only {drawn} coloured pixels");
            checked += 1;
        }
    }
    assert!(checked >= 12, "{checked}");
    // the check can fail: a chart with axes and no data shows (almost) no coloured pixel
    let empty = musculo::report::line_chart("empty", "y", &[0.0, 1.0], &[], 300).unwrap();
    let one = dir.join("empty.html");
    std::fs::write(
        &one,
        format!("<html><body style=\"margin:0\">{empty}</body></html>"),
    )
    .unwrap();
    let png = dir.join("empty.png");
    std::process::Command::new(&browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
        ])
        .arg("--window-size=900,300")
        .arg(format!("--screenshot={}", png.display()))
        .arg(format!("file://{}", one.display()))
        .output()
        .expect("run chromium");
    let drawn = coloured_pixels(&png);
    println!("an empty chart: {drawn} coloured pixels");
    assert!(drawn < 300, "{drawn}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_training_page_plots_every_nonzero_loss_column_on_a_log_scale() {
    let csv = "step,total,reconstruction,euler,muscle,seconds\n\
               0,1e1,1e0,9e0,0e0,0.1\n\
               1,1e0,1e-1,9e-1,0e0,0.2\n\
               2,1e-1,1e-2,9e-2,0e0,0.3\n";
    let html = musculo::report::training_page("run", "loss.csv", csv).unwrap();
    let figures = plots(&html);
    assert_eq!(figures.len(), 1);
    let svg = &figures[0].1;
    // one legend entry per loss column that is not zero throughout, no `seconds`
    for name in ["total", "reconstruction", "euler"] {
        assert!(svg.contains(name), "{name}");
    }
    for absent in ["muscle", "seconds"] {
        assert!(!svg.contains(absent), "{absent}");
    }
    // log₁₀ scale: the axis spans −2 … 1
    assert!(svg.contains("log₁₀ loss"));
    let err = musculo::report::training_page("run", "loss.csv", "step,total\n0,1\n1,x\n")
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("loss.csv: line 3"), "{err}");
}

#[test]
fn a_sharded_run_gets_its_dataset_page_from_merge() {
    // two shards with --report write no page; `merge --report` writes the page an unsharded
    // `augment --report` writes (the same bytes, but for the folder's name in the title)
    let dir = temp_dir("shards");
    let (one, out) = (dir.join("one"), dir.join("aug"));
    let (ok, _, err) = musculo_cli("augment --demo --report --out {}", &[&one]);
    assert!(ok, "{err}");
    for shard in ["0/2", "1/2"] {
        let (ok, _, err) = musculo_cli(
            &format!("augment --demo --report --shard {shard} --out {{}}"),
            &[&out],
        );
        assert!(ok, "{err}");
        assert!(err.contains("musculo merge --report"), "{err}");
    }
    assert!(
        !out.join("report/index.html").exists(),
        "a shard wrote the page"
    );
    let (ok, _, err) = musculo_cli("merge --report {}", &[&out]);
    assert!(ok, "{err}");
    let page = |d: &Path| {
        std::fs::read_to_string(d.join("report/index.html"))
            .unwrap()
            .replace(&d.display().to_string(), "OUT")
    };
    let merged = page(&out);
    for clip in ["march", "squat", "reach"] {
        assert!(merged.contains(clip), "{clip}");
    }
    assert_eq!(merged, page(&one));
    let _ = std::fs::remove_dir_all(dir);
}
