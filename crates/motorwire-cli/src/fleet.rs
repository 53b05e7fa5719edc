//! `motorwire bridge --zenoh`: the bridge joins a fleet as a Zenoh
//! participant beside its other inputs (motorwire-zenoh).
//!
//! The fleet is the `fleet` cargo feature: Zenoh is most of the crates a
//! build with it compiles, so the default build leaves it out. A binary
//! built without it still knows the fleet's options, and answers
//! `--zenoh` with exit 2 and the command that builds the fleet in
//! ([`WITHOUT_FLEET`]).

#[cfg(feature = "fleet")]
use std::time::Duration;

use motorwire_bridge::{InputSender, Output};
#[cfg(feature = "fleet")]
use motorwire_zenoh::{FleetConfig, Participant, config_from_file};

/// What a binary built without the `fleet` feature answers `--zenoh` with
/// (and says in `--help`): the exact commands that build it in.
pub(crate) const WITHOUT_FLEET: &str = "this motorwire was built without the fleet (the `fleet` feature): build it with `cargo build --release -p motorwire-cli --features fleet` in the repository, or install it with `cargo install --path crates/motorwire-cli --features fleet`";

#[derive(Debug, clap::Args)]
#[cfg_attr(not(feature = "fleet"), allow(dead_code))]
pub(crate) struct ZenohArgs {
    /// Join a Zenoh fleet: commands as queries on motorwire/ROBOT/cmd,
    /// feedback and events published, a liveliness token, and the fleet's
    /// emergency stop (motorwire/fleet/estop), beside the other inputs.
    /// The bridge then reads no standard input unless `--input -` says
    /// to (it ends at the end of standard input).
    #[cfg_attr(
        not(feature = "fleet"),
        doc = "Not in this build: it was built without the fleet (the `fleet` feature). Build it with `cargo build --release -p motorwire-cli --features fleet` in the repository, or install it with `cargo install --path crates/motorwire-cli --features fleet`."
    )]
    #[arg(long)]
    zenoh: bool,
    /// The robot's name in the fleet's key expressions (default: the host
    /// name). One bridge per name: when another bridge answers for it
    /// already, this one exits 2 naming that bridge.
    #[arg(long, value_name = "NAME", requires = "zenoh")]
    robot: Option<String>,
    /// The Zenoh configuration (JSON5): mode, endpoints, TLS,
    /// authentication, access control. Without it, Zenoh's defaults (a
    /// peer that scouts by multicast, no TLS).
    #[arg(long, value_name = "FILE", requires = "zenoh")]
    zenoh_config: Option<String>,
    /// With `--zenoh`: a session with no router or peer for this long
    /// while joints move (or a command is in progress) stops them.
    #[arg(long, value_name = "MS", default_value_t = 500)]
    zenoh_session_timeout: u64,
}

impl ZenohArgs {
    /// Whether `--zenoh` was given.
    pub(crate) const fn enabled(&self) -> bool {
        self.zenoh
    }
}

/// Refuses `--zenoh` in a build without the fleet, before the bridge
/// opens anything.
pub(crate) fn check(args: &ZenohArgs) -> Result<(), String> {
    if args.zenoh && !cfg!(feature = "fleet") {
        return Err(format!("--zenoh: {WITHOUT_FLEET}"));
    }
    Ok(())
}

/// The host's name, as a robot name (`robot` when it has none usable).
#[cfg(feature = "fleet")]
fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|s| s.trim().to_owned())
        .filter(|s| motorwire_zenoh::RobotKeys::new(s).is_ok())
        .unwrap_or_else(|| "robot".to_owned())
}

/// Starts the participant when `--zenoh` was given.
#[cfg(feature = "fleet")]
pub(crate) fn start(args: &ZenohArgs, input: InputSender) -> Result<Option<Fleet>, String> {
    if !args.zenoh {
        return Ok(None);
    }
    let robot = args.robot.clone().unwrap_or_else(host_name);
    let zenoh = match &args.zenoh_config {
        Some(path) => config_from_file(path).map_err(|e| format!("--zenoh-config {e}"))?,
        None => motorwire_zenoh::zenoh::Config::default(),
    };
    let mut config = FleetConfig::new(&robot, zenoh).map_err(|e| format!("--robot {e}"))?;
    config.session_timeout = Duration::from_millis(args.zenoh_session_timeout.max(1));
    let participant = Participant::start(config, input, |what: &str| {
        crate::console::note!("motorwire bridge: {what}");
    })
    .map_err(|e| format!("--zenoh: {e}"))?;
    Ok(Some(Fleet(participant)))
}

/// Without the fleet there is never a participant: [`check`] has refused
/// `--zenoh` already.
#[cfg(not(feature = "fleet"))]
pub(crate) fn start(args: &ZenohArgs, _input: InputSender) -> Result<Option<Fleet>, String> {
    check(args).map(|()| None)
}

/// The running participant.
#[cfg(feature = "fleet")]
#[derive(Debug)]
pub(crate) struct Fleet(Participant);

/// The running participant (none without the fleet).
#[cfg(not(feature = "fleet"))]
#[derive(Debug)]
pub(crate) enum Fleet {}

#[cfg(feature = "fleet")]
impl Fleet {
    /// Takes one output; `true` when it was the participant's alone.
    pub(crate) fn route(&self, o: &Output) -> bool {
        self.0.route(o)
    }

    /// Withdraws the token and closes the session.
    pub(crate) fn close(self) {
        self.0.close();
    }
}

#[cfg(not(feature = "fleet"))]
impl Fleet {
    /// Never called: there is no participant.
    pub(crate) fn route(&self, _o: &Output) -> bool {
        match *self {}
    }

    /// Never called: there is no participant.
    pub(crate) fn close(self) {
        match self {}
    }
}
