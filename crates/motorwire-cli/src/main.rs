#![doc = include_str!("../README.md")]
// println!/eprintln! panic on a closed pipe: `console::say!`/`note!` instead.
#![deny(clippy::print_stdout, clippy::print_stderr)]

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod bridge;
mod bus;
mod candump;
mod chart;
mod compact;
mod console;
mod demo;
mod fleet;
mod input;
mod irpc;
mod lines;
mod moteus;
mod orion_link;
mod plan;
mod plot;
mod replay;
mod serve;
mod servo;
mod servo_calibrate;
mod servo_import;
mod sim;
mod sim_servos;
mod translate;
mod validate;
mod view;

/// The allocator (the `jemalloc` feature, on by default): memory a thread
/// frees for another is kept for reuse, not given back to the kernel and
/// faulted in again on the bridge's thread in the middle of a stop.
#[cfg(all(feature = "jemalloc", not(target_env = "msvc")))]
#[global_allocator]
static ALLOCATOR: tikv_jemallocator::Jemalloc = tikv_jemallocator::Jemalloc;

/// Typed, validated, safe messages between the software that decides a
/// motion and the motors that make it.
#[derive(Debug, Parser)]
#[command(name = "motorwire", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Validate WIA JSON messages against the JSON Schemas and WIA §10.
    Validate(validate::Args),
    /// Encode and decode iRPC messages (JSON lines <-> hex lines).
    Irpc(irpc::Args),
    /// Encode and decode the 24-byte WIA compact command.
    Compact(compact::Args),
    /// Encode and decode mjbots moteus frames (JSON lines with the names of
    /// mjbots' Python library <-> `{"can_id":N,"data":"hex"}` lines), built
    /// and read by mjbots' `moteus-protocol` crate.
    Moteus(moteus::Args),
    /// Encode and decode serial bus servo packets (Feetech STS/SMS and SCS,
    /// Dynamixel Protocol 2.0: JSON lines in the vendors' terms <->
    /// `{"bytes":"hex"}` lines), byte for byte as the vendors' SDKs.
    Servo(servo::Args),
    /// Translate WIA command lines into one target dialect (iRPC frames,
    /// compact-command frames or Orion JSON) through the bridge's gate:
    /// one result line per input line, with the translation's loss report.
    ///
    /// Exit status 0 when every line was translated, 1 when any was
    /// refused, 2 on a usage error (a bad map, an unknown --to).
    Translate(translate::Args),
    /// Plan motion profiles: JSON move requests in, one JSON line (or CSV
    /// samples, or an SVG plot) out per move.
    Plan(plan::Args),
    /// Run a simulated device.
    Sim(sim::Args),
    /// Decode `candump -L` logs.
    Candump(candump::Args),
    /// Bridge WIA JSON commands onto iRPC joints on a CAN bus (or a
    /// simulated arm): one result line per input line, feedback and events
    /// as they come.
    ///
    /// SIGINT, SIGTERM and SIGHUP stop and deactivate the joints, then end
    /// the bridge with exit status 130, 143 or 129; a second signal exits
    /// at once. Exit status 0 after the end of input, 2 on an error, 74
    /// when standard output stopped being read or failed.
    Bridge(Box<bridge::Args>),
    /// Run the bridge on a simulated arm (3 iRPC joints, a compact-command
    /// gripper and the Orion arm's 7 motors, no hardware) through a
    /// scripted session, checking each step.
    ///
    /// The map is the built-in copy of fixtures/maps/demo-arm.toml. In order:
    /// the WIA document's multi-axis example (3 joints, synchronized, 2 s), a
    /// move, a synchronized move, a trajectory through a waypoint at speed,
    /// the gripper closed, the Orion turntable turned and then stopped by the
    /// deadman once its commands stop, an unsafe command refused (elbow
    /// beyond its limit), a move interrupted by an emergency stop (every
    /// motor of the map), a command refused
    /// while the stop is latched, the release, a move back and the gripper
    /// opened. Prints each step and its result, then a summary (each step,
    /// each device's final position against its target) and writes --svg,
    /// the positions and velocities from the feedback (about 9 s).
    ///
    /// Exit status 0 only if every expectation held, 1 otherwise, 2 when
    /// standard output closes.
    Demo(demo::Args),
    /// Replay a recording (`motorwire bridge --record DIR`): its input
    /// lines, at their recorded times, into the bridge on the simulated bus
    /// (simulated time, faster than real time unless --real-time), and
    /// compare what comes out with what was recorded: each line's answers,
    /// the events, the frames sent to each device and the lines written to
    /// the Orion controller, in order, leaving out what the clock decides
    /// (latencies, msg_ids, timestamps, heartbeats, retries, feedback).
    ///
    /// Prints what was compared and the first divergence with both sides
    /// and its time. Exit status 0 when the replay gave the same, 1 on a
    /// divergence, 2 when the recording cannot be replayed (unreadable,
    /// rotated, records dropped, no setup).
    Replay(replay::Args),
    /// Draw a recording (`motorwire bridge --record DIR`) as an SVG: one
    /// panel per motor (its position with its target and its limits as
    /// bands, its velocity with its speed limit; an Orion motor's
    /// commanded speed in the controller's units), the events (stops,
    /// releases, refusals with their rule, deadman stops, devices and
    /// links lost) as numbered marks with a key, units on the axes.
    ///
    /// Exit status 0 when drawn, 2 when the recording cannot be read or
    /// the file written.
    Plot(plot::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let status = match cli.command {
        Command::Validate(args) => validate::run(&args),
        Command::Irpc(args) => irpc::run(&args),
        Command::Compact(args) => compact::run(&args),
        Command::Moteus(args) => moteus::run(&args),
        Command::Servo(args) => servo::run(&args),
        Command::Translate(args) => translate::run(&args),
        Command::Plan(args) => plan::run(&args),
        Command::Sim(args) => sim::run(&args),
        Command::Candump(args) => candump::run(&args),
        Command::Bridge(args) => bridge::run(&args),
        Command::Demo(args) => demo::run(&args),
        Command::Replay(args) => replay::run(&args),
        Command::Plot(args) => plot::run(&args),
    };
    ExitCode::from(status)
}
