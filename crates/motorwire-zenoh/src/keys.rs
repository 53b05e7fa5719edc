//! The key expressions of a robot and of the fleet.

use crate::ZenohError;
use crate::ids::Controller;

/// Where every bridge of the fleet listens for the fleet's emergency stop
/// (a put, any payload).
pub const FLEET_ESTOP: &str = "motorwire/fleet/estop";

/// The name `fleet` is taken by [`FLEET_ESTOP`].
const RESERVED: &str = "fleet";

/// The key expressions of one robot, `motorwire/<robot>/...`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RobotKeys {
    robot: String,
}

impl RobotKeys {
    /// The keys of `robot`: a non-empty key-expression chunk (no `/`, `*`,
    /// `$`, `?`, `#`, whitespace or control character), at most 64 bytes,
    /// not `fleet`.
    ///
    /// # Errors
    /// [`ZenohError::RobotName`] when the name cannot be used.
    pub fn new(robot: &str) -> Result<Self, ZenohError> {
        check_chunk(robot).map_err(|why| ZenohError::RobotName {
            name: robot.to_owned(),
            why,
        })?;
        if robot == RESERVED {
            return Err(ZenohError::RobotName {
                name: robot.to_owned(),
                why: "`fleet` is the fleet's own (motorwire/fleet/estop)",
            });
        }
        Ok(Self {
            robot: robot.to_owned(),
        })
    }

    /// The robot's name.
    pub fn robot(&self) -> &str {
        &self.robot
    }

    /// `motorwire/<robot>/cmd`: commands, as queries.
    pub fn cmd(&self) -> String {
        format!("motorwire/{}/cmd", self.robot)
    }

    /// `motorwire/<robot>/cmd/<controller>`: the commands of one
    /// controller, as queries (its ids are its own; with the router's
    /// access control, only the user `controller` may query it).
    ///
    /// # Errors
    /// Why `controller` cannot be one key-expression chunk.
    pub fn cmd_of(&self, controller: &str) -> Result<String, &'static str> {
        check_chunk(controller)?;
        Ok(format!("motorwire/{}/cmd/{controller}", self.robot))
    }

    /// The key the replies to `controller`'s commands go on: this robot's
    /// `cmd/<controller>`, or `cmd` for a controller named by parameter.
    pub(crate) fn reply_key(&self, controller: &Controller) -> String {
        match controller {
            Controller::Key(c) => format!("motorwire/{}/cmd/{c}", self.robot),
            Controller::Named(_) => self.cmd(),
        }
    }

    /// `motorwire/<robot>/cmd/**`: what the bridge's queryable serves
    /// (`cmd` itself and every `cmd/<controller>`).
    pub fn cmd_any(&self) -> String {
        format!("motorwire/{}/cmd/**", self.robot)
    }

    /// `motorwire/<robot>/estop`: this robot's emergency stop, as a put.
    pub fn estop(&self) -> String {
        format!("motorwire/{}/estop", self.robot)
    }

    /// `motorwire/<robot>/estop/result`: the result line of each stop put
    /// heard (with its `stop_latency_us`).
    pub fn estop_result(&self) -> String {
        format!("motorwire/{}/estop/result", self.robot)
    }

    /// `motorwire/<robot>/event`: the bridge's events.
    pub fn event(&self) -> String {
        format!("motorwire/{}/event", self.robot)
    }

    /// `motorwire/<robot>/alive`: the bridge's liveliness token.
    pub fn alive(&self) -> String {
        format!("motorwire/{}/alive", self.robot)
    }

    /// `motorwire/<robot>/alive/<bridge>`: one bridge's own liveliness
    /// token, `bridge` its Zenoh id (how a bridge starting with a name
    /// already taken finds the bridge that has it).
    pub fn alive_bridge(&self, bridge: &str) -> String {
        format!("motorwire/{}/alive/{bridge}", self.robot)
    }

    /// `motorwire/<robot>/alive/*`: every bridge's token for this robot.
    pub fn alive_bridges(&self) -> String {
        format!("motorwire/{}/alive/*", self.robot)
    }

    /// `motorwire/<robot>/feedback/<motor_id>`, or `None` when the motor's
    /// id cannot be a key-expression chunk (its feedback is then not
    /// published).
    pub fn feedback(&self, motor_id: &str) -> Option<String> {
        check_chunk(motor_id).ok()?;
        Some(format!("motorwire/{}/feedback/{motor_id}", self.robot))
    }
}

/// Whose command a query on `key` (with the selector parameter
/// `controller`, when it has one) is: [`Controller::Key`] for
/// `motorwire/<robot>/cmd/<controller>`, [`Controller::Named`] for
/// `motorwire/<robot>/cmd` (the parameter, or `""`). The robot chunk may
/// be a wildcard (the query reached this bridge); the controller chunk may
/// not, nor may a query name its controller both ways.
///
/// # Errors
/// Why the query names no one controller, for a person.
pub(crate) fn controller_of(key: &str, parameter: Option<&str>) -> Result<Controller, String> {
    let chunks: Vec<&str> = key.split('/').collect();
    match chunks.as_slice() {
        ["motorwire", robot, "cmd"] if *robot != "**" => {
            Ok(Controller::Named(parameter.unwrap_or("").to_owned()))
        }
        ["motorwire", robot, "cmd", controller] if *robot != "**" => {
            check_chunk(controller).map_err(|why| {
                format!(
                    "the controller chunk {controller:?} of the key {key}: {why}; a command is asked on motorwire/<robot>/cmd/<controller>, one controller by its name"
                )
            })?;
            if parameter.is_some() {
                return Err(format!(
                    "the key {key} names the controller {controller:?} and the `controller` parameter names one too; name it once, by the key"
                ));
            }
            Ok(Controller::Key((*controller).to_owned()))
        }
        _ => Err(format!(
            "the key {key} names no one controller: a command is asked on motorwire/<robot>/cmd/<controller> (or motorwire/<robot>/cmd)"
        )),
    }
}

/// Whether `s` can be one chunk of a key expression, and why not.
fn check_chunk(s: &str) -> Result<(), &'static str> {
    if s.is_empty() {
        return Err("empty");
    }
    if s.len() > 64 {
        return Err("longer than 64 bytes");
    }
    if s.chars()
        .any(|c| matches!(c, '/' | '*' | '$' | '?' | '#') || c.is_whitespace() || c.is_control())
    {
        return Err(
            "a key-expression chunk cannot hold `/`, `*`, `$`, `?`, `#`, spaces or control characters",
        );
    }
    if s.starts_with('@') {
        return Err(
            "a chunk that starts with `@` is verbatim: no wildcard finds it (`motorwire/*/alive` would not)",
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_of_a_robot() {
        let k = RobotKeys::new("arm-1").ok();
        let k = k.as_ref();
        assert_eq!(
            k.map(RobotKeys::cmd).as_deref(),
            Some("motorwire/arm-1/cmd")
        );
        assert_eq!(
            k.map(RobotKeys::estop).as_deref(),
            Some("motorwire/arm-1/estop")
        );
        assert_eq!(
            k.map(RobotKeys::alive).as_deref(),
            Some("motorwire/arm-1/alive")
        );
        assert_eq!(
            k.map(|k| k.alive_bridge("a1b2")).as_deref(),
            Some("motorwire/arm-1/alive/a1b2")
        );
        assert_eq!(
            k.map(RobotKeys::alive_bridges).as_deref(),
            Some("motorwire/arm-1/alive/*")
        );
        assert_eq!(
            k.map(RobotKeys::event).as_deref(),
            Some("motorwire/arm-1/event")
        );
        assert_eq!(
            k.and_then(|k| k.feedback("elbow")).as_deref(),
            Some("motorwire/arm-1/feedback/elbow")
        );
        assert_eq!(k.and_then(|k| k.feedback("a/b")), None);
        assert_eq!(
            k.map(|k| k.cmd_of("planner")),
            Some(Ok("motorwire/arm-1/cmd/planner".to_owned()))
        );
        assert_eq!(
            k.map(|k| k.cmd_of("*")),
            Some(Err(
                "a key-expression chunk cannot hold `/`, `*`, `$`, `?`, `#`, spaces or control characters"
            ))
        );
        assert_eq!(
            k.map(RobotKeys::cmd_any).as_deref(),
            Some("motorwire/arm-1/cmd/**")
        );
        assert_eq!(
            k.map(|k| k.reply_key(&Controller::Key("planner".into())))
                .as_deref(),
            Some("motorwire/arm-1/cmd/planner")
        );
        assert_eq!(
            k.map(|k| k.reply_key(&Controller::Named("planner".into())))
                .as_deref(),
            Some("motorwire/arm-1/cmd")
        );
    }

    #[test]
    fn a_query_names_one_controller_by_its_key_or_by_its_parameter() {
        let key = |c: &str| Ok(Controller::Key(c.to_owned()));
        let named = |c: &str| Ok(Controller::Named(c.to_owned()));
        assert_eq!(controller_of("motorwire/arm/cmd/alice", None), key("alice"));
        assert_eq!(controller_of("motorwire/*/cmd/alice", None), key("alice"));
        assert_eq!(controller_of("motorwire/arm/cmd", None), named(""));
        assert_eq!(
            controller_of("motorwire/arm/cmd", Some("alice")),
            named("alice")
        );
        assert_eq!(controller_of("motorwire/*/cmd", Some("")), named(""));
        assert_eq!(
            controller_of("motorwire/arm/cmd/alice", Some("bob")),
            Err(
                r#"the key motorwire/arm/cmd/alice names the controller "alice" and the `controller` parameter names one too; name it once, by the key"#
                    .to_owned()
            )
        );
        assert_eq!(
            controller_of("motorwire/arm/cmd/*", None),
            Err(
                r#"the controller chunk "*" of the key motorwire/arm/cmd/*: a key-expression chunk cannot hold `/`, `*`, `$`, `?`, `#`, spaces or control characters; a command is asked on motorwire/<robot>/cmd/<controller>, one controller by its name"#
                    .to_owned()
            )
        );
        for wild in [
            "motorwire/arm/cmd/**",
            "motorwire/arm/cmd/a$*",
            "motorwire/arm/cmd/@alice",
            "motorwire/arm/cmd/alice/x",
            "motorwire/arm/**",
            "motorwire/**",
            "motorwire/**/cmd",
            "motorwire/**/cmd/alice",
            "**",
            "motorwire/arm/c*",
        ] {
            assert!(controller_of(wild, None).is_err(), "{wild} accepted");
        }
        assert_eq!(
            controller_of("motorwire/**", None),
            Err(
                "the key motorwire/** names no one controller: a command is asked on motorwire/<robot>/cmd/<controller> (or motorwire/<robot>/cmd)"
                    .to_owned()
            )
        );
    }

    #[test]
    fn names_that_are_not_one_chunk_are_refused() {
        for bad in [
            "",
            "a/b",
            "*",
            "a*",
            "$x",
            "a?b",
            "a#",
            "a b",
            "fleet",
            "@lab",
            "@",
            &"x".repeat(65),
        ] {
            assert!(RobotKeys::new(bad).is_err(), "{bad:?} accepted");
        }
        assert!(RobotKeys::new(&"x".repeat(64)).is_ok());
        assert!(RobotKeys::new("lab@2").is_ok());
        let why = RobotKeys::new("@lab").err().map(|e| e.to_string());
        assert_eq!(
            why.as_deref(),
            Some(
                "robot name \"@lab\": a chunk that starts with `@` is verbatim: no wildcard finds it (`motorwire/*/alive` would not)"
            )
        );
    }
}
