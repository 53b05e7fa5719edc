//! Plan a jerk-limited S-curve move and sample it.
//!
//! ```sh
//! cargo run --example scurve
//! ```
//!
//! The iRPC document's example move: 0 to 90° at up to 100 °/s, 500 °/s²
//! and 2000 °/s³, from rest to rest. `plan` is time-optimal under those
//! limits; `sample(t)` is the state at any instant (a joint samples it at
//! its control rate; nothing is stored per step). The same move from an
//! iRPC `SetTargetV2` is `SetTargetPayloadV2::planner_request` (feature
//! `planner` of motorwire-irpc).

use std::io::Write;

use motorwire_planner::{PlannerMotionProfile, Request, plan};

fn run(out: &mut dyn Write) -> Result<(), Box<dyn std::error::Error>> {
    let request = Request::new(0.0f64, 90.0, 100.0, 500.0)
        .with_jerk(2000.0)
        .with_profile(PlannerMotionProfile::SCurve);
    let profile = plan(&request)?;
    writeln!(
        out,
        "duration {:.4} s, {} phases, peak velocity {:.1} deg/s",
        profile.duration(),
        profile.phase_count(),
        profile.peak_velocity().0
    )?;
    writeln!(
        out,
        "t (s)  position (deg)  velocity (deg/s)  acceleration (deg/s²)  jerk (deg/s³)"
    )?;
    let steps = 7u32;
    for i in 0..=steps {
        let t = profile.duration() * f64::from(i) / f64::from(steps);
        let s = profile.sample(t);
        writeln!(
            out,
            "{t:5.3}  {:14.3}  {:16.3}  {:21.1}  {:13.0}",
            s.position, s.velocity, s.acceleration, s.jerk
        )?;
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run(&mut std::io::stdout()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("scurve: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    /// The output, exactly.
    const EXPECTED: &str = r##"duration 1.3472 s, 5 phases, peak velocity 100.0 deg/s
t (s)  position (deg)  velocity (deg/s)  acceleration (deg/s²)  jerk (deg/s³)
0.000           0.000             0.000                    0.0           2000
0.192           2.376            37.040                  384.9           2000
0.385          16.212            96.119                  124.6          -2000
0.577          35.377           100.000                    0.0              0
0.770          54.623           100.000                    0.0              0
0.962          73.788            96.119                 -124.6          -2000
1.155          87.624            37.040                 -384.9           2000
1.347          90.000             0.000                   -0.0           2000
"##;

    #[test]
    fn plans_and_samples_the_documents_move() {
        let mut out = Vec::new();
        assert!(super::run(&mut out).is_ok());
        assert_eq!(String::from_utf8_lossy(&out), EXPECTED);
    }
}
