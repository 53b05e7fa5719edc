//! `motorwire plan`, run as a user runs it.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod common;

use std::process::Output;

use serde_json::Value;

fn motorwire(args: &[&str], stdin: &str) -> Output {
    common::run(args, stdin.as_bytes())
}

const EXAMPLE: &str = r#"{"start":0,"target":90,"start_velocity":0,"target_velocity":0,"max_velocity":100,"max_acceleration":500,"max_deceleration":500,"max_jerk":2000,"profile":"scurve"}"#;

#[test]
fn answers_the_irpc_documents_example() {
    let out = motorwire(&["plan"], &format!("{EXAMPLE}\n"));
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let d = v["duration"].as_f64().unwrap();
    assert!((d - (0.9 + 0.2f64.sqrt())).abs() < 1e-12, "{d}");
    assert_eq!(v["peak_velocity"], 100.0);
    assert_eq!(v["overshoot"], false);
    let phases = v["phases"].as_array().unwrap();
    assert_eq!(phases.len(), 5);
    let jerks: Vec<f64> = phases.iter().map(|p| p["jerk"].as_f64().unwrap()).collect();
    assert_eq!(jerks, [2000.0, -2000.0, 0.0, -2000.0, 2000.0]);
    let total: f64 = phases.iter().map(|p| p["duration"].as_f64().unwrap()).sum();
    assert!((total - d).abs() < 1e-12);
}

#[test]
fn a_bad_line_is_an_error_line_and_the_rest_goes_on() {
    let input = format!(
        "{EXAMPLE}\n{{\"start\":0,\"target\":1,\"max_velocity\":0,\"max_acceleration\":1}}\n{{\"start\":\"x\"}}\n{{\"start\":0,\"target\":1,\"max_velocity\":1,\"max_acceleration\":1,\"profile\":\"scurve\"}}\n{EXAMPLE}\n"
    );
    let out = motorwire(&["plan"], &input);
    assert_eq!(out.status.code(), Some(1));
    let lines: Vec<Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 5);
    assert!(lines[0]["duration"].is_f64());
    assert_eq!(lines[1]["error"], "max_velocity must be > 0 (got 0)");
    assert_eq!(lines[1]["line"], 2);
    assert!(
        lines[2]["error"]
            .as_str()
            .unwrap()
            .starts_with("bad request: invalid type")
    );
    assert_eq!(
        lines[3]["error"],
        "max_jerk is required for an S-curve profile"
    );
    assert!(lines[4]["duration"].is_f64());
}

#[test]
fn samples_as_csv_on_an_integer_tick() {
    let input = r#"{"start":0,"target":90,"max_velocity":100,"max_acceleration":500,"profile":"trapezoidal"}"#;
    let out = motorwire(&["plan", "--sample", "0.1"], &format!("{input}\n"));
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows[0], "t,position,velocity,acceleration,jerk");
    assert_eq!(rows[1], "0.000000,0,0,500,0");
    assert_eq!(rows[2], "0.100000,2.5,50,500,0");
    assert_eq!(rows.last().unwrap(), &"1.100000,90,0,0,0");
    assert_eq!(rows.len(), 1 + 12);
    let bad = motorwire(&["plan", "--sample", "0.0000001"], &format!("{input}\n"));
    assert_eq!(bad.status.code(), Some(2));
}

#[test]
fn exact_duration_and_f32() {
    let out = motorwire(
        &["plan", "--duration", "2", "--precision", "f32"],
        &format!("{EXAMPLE}\n"),
    );
    assert_eq!(out.status.code(), Some(0));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!((v["duration"].as_f64().unwrap() - 2.0).abs() < 1e-5);
    assert!(v["peak_velocity"].as_f64().unwrap() < 100.0);
    let out = motorwire(&["plan", "--duration", "1"], &format!("{EXAMPLE}\n"));
    assert_eq!(out.status.code(), Some(1));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(
        v["error"]
            .as_str()
            .unwrap()
            .contains("shorter than the fastest profile")
    );
}

#[test]
fn draws_an_svg_with_the_four_quantities() {
    let dir = std::env::temp_dir().join(format!("motorwire-plan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("move.svg");
    let input = format!("{EXAMPLE}\n{EXAMPLE}\n");
    let out = motorwire(&["plan", "--plot", path.to_str().unwrap()], &input);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for file in [path.clone(), dir.join("move-2.svg")] {
        let svg = std::fs::read_to_string(&file).unwrap();
        assert!(svg.starts_with("<svg"), "{file:?}");
        // Each of the four panels: a caption and a y axis in its unit, and
        // an x axis in seconds.
        for label in [
            "position (deg)",
            "velocity (deg/s)",
            "acceleration (deg/s²)",
            "jerk (deg/s³)",
        ] {
            assert_eq!(svg.matches(label).count(), 2, "{file:?}: {label}");
        }
        assert_eq!(svg.matches("time (s)").count(), 4, "{file:?}");
        assert!(svg.matches("<polyline").count() >= 4);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_plot_names_the_unit_given() {
    let dir = std::env::temp_dir().join(format!("motorwire-plan-unit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("move.svg");
    let out = motorwire(
        &["plan", "--unit", "rad", "--plot", path.to_str().unwrap()],
        &format!("{EXAMPLE}\n"),
    );
    assert_eq!(out.status.code(), Some(0));
    let svg = std::fs::read_to_string(&path).unwrap();
    for label in [
        "position (rad)",
        "velocity (rad/s)",
        "acceleration (rad/s²)",
        "jerk (rad/s³)",
    ] {
        assert_eq!(svg.matches(label).count(), 2, "{label}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
