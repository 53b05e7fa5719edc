//! Unknown members: every object member of a document that its kind's JSON
//! Schema does not name, found by one scan of the text (nothing parsed
//! again), with the nearest member the schema does name.
//!
//! WIA's schemas leave `additionalProperties` open, so a misspelled
//! `velocity_limt` is valid WIA and would be ignored: in a motor command a
//! typo is a safety problem. [`Validator::deny_unknown_members`]
//! (crate::Validator::deny_unknown_members) refuses them.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::sync::OnceLock;

use serde_json::Value;

use crate::{MessageKind, Rule, Violation};

/// What a kind's schema says of one place in a document: the member names
/// an object there may have (each with what it says of that member's
/// value), or nothing (any member, as `metadata`), and what it says of an
/// array's items.
#[derive(Debug, Default)]
struct Known {
    members: Option<BTreeMap<String, Known>>,
    items: Option<Box<Known>>,
}

impl Known {
    /// `node` of the schema `root`, its `$ref`s (`#/definitions/...`)
    /// followed at most `depth` times.
    fn of(root: &Value, node: &Value, depth: usize) -> Self {
        let node = match node.get("$ref").and_then(Value::as_str) {
            Some(r) if depth > 0 => r
                .strip_prefix("#/")
                .and_then(|path| path.split('/').try_fold(root, |v, k| v.get(k)))
                .unwrap_or(node),
            _ => node,
        };
        let members = node.get("properties").and_then(Value::as_object).map(|p| {
            p.iter()
                .map(|(k, v)| (k.clone(), Self::of(root, v, depth.saturating_sub(1))))
                .collect()
        });
        let items = node
            .get("items")
            .map(|i| Box::new(Self::of(root, i, depth.saturating_sub(1))));
        Self { members, items }
    }
}

fn known(kind: MessageKind) -> &'static Known {
    static ALL: OnceLock<Vec<(MessageKind, Known)>> = OnceLock::new();
    let all = ALL.get_or_init(|| {
        MessageKind::ALL
            .iter()
            .map(|k| {
                let schema: Value = serde_json::from_str(k.schema()).unwrap_or(Value::Null);
                let mut known = Known::of(&schema, &schema, 16);
                // motorwire's one member of a command beyond WIA's:
                // `stream` (a boolean; each command's check holds it to one).
                if matches!(k, MessageKind::MotorCommand | MessageKind::MultiAxisCommand)
                    && let Some(m) = known.members.as_mut()
                {
                    m.insert(STREAM.to_owned(), Known::default());
                }
                (*k, known)
            })
            .collect()
    });
    static NOTHING: Known = Known {
        members: None,
        items: None,
    };
    all.iter()
        .find(|(k, _)| *k == kind)
        .map_or(&NOTHING, |(_, known)| known)
}

/// The names `kind`'s schema gives a document's top-level members, made
/// once from the schema as the scan reads it.
pub(crate) fn top_level_members(kind: MessageKind) -> &'static [&'static str] {
    static ALL: OnceLock<Vec<(MessageKind, Vec<&'static str>)>> = OnceLock::new();
    let all = ALL.get_or_init(|| {
        MessageKind::ALL
            .iter()
            .map(|k| {
                // WIA's names alone: a line with motorwire's `stream` is
                // not a plain command (the bridge reads it as a stream's).
                let names = known(*k)
                    .members
                    .iter()
                    .flat_map(|m| m.keys().map(String::as_str))
                    .filter(|n| *n != STREAM)
                    .collect();
                (*k, names)
            })
            .collect()
    });
    all.iter()
        .find(|(k, _)| *k == kind)
        .map_or(&[], |(_, names)| names.as_slice())
}

/// One open object or array of the scan, with what the schema says of it
/// (`None`: anything goes below).
enum Frame<'k, 't> {
    Object {
        known: Option<&'k Known>,
        /// The member whose value comes next (its name, and what the
        /// schema says of it).
        key: Option<(Cow<'t, str>, Option<&'k Known>)>,
    },
    Array {
        known: Option<&'k Known>,
        index: usize,
    },
}

/// Whether a typed message kept any member its schema does not name: the
/// command types say exactly (their `extra` maps, at every level), so a
/// clean command skips the scan; the others say `true` (scanned).
pub(crate) trait Unknowns {
    /// `false` when no `extra` map of the value holds anything.
    fn any_unknown(&self) -> bool {
        true
    }
}

impl Unknowns for crate::MotorFeedback {}
impl Unknowns for crate::Trajectory {}
impl Unknowns for crate::PidConfig {}
impl Unknowns for crate::SafetyLimits {}
impl Unknowns for crate::ControlModeConfig {}

fn any_in_parts(
    pid: Option<&crate::PidGains>,
    impedance: Option<&crate::ImpedanceParams>,
    filter: Option<&crate::FilterConfig>,
    safety: Option<&crate::CommandSafetyLimits>,
) -> bool {
    pid.is_some_and(|p| !p.extra.is_empty())
        || impedance.is_some_and(|p| !p.extra.is_empty())
        || filter.is_some_and(|p| !p.extra.is_empty())
        || safety.is_some_and(|p| !p.extra.is_empty())
}

/// The member a MotorCommand or a multi-axis command may carry beyond
/// WIA's: `"stream": true` makes it a setpoint of a policy's stream (the
/// bridge's; a multi-axis one sets each of its motors in one line).
pub const STREAM: &str = "stream";

/// Why a multi-axis command with `"stream": true` cannot be `sync_mode`
/// `sequential` (rule `stream`, at `/sync_mode`).
pub const STREAM_SEQUENTIAL: &str = "a stream's setpoints go at once; sync_mode sequential waits for each axis to arrive: a stream line is simultaneous or independent";

impl Unknowns for crate::MotorCommand {
    fn any_unknown(&self) -> bool {
        self.extra.keys().any(|k| k != STREAM)
            || any_in_parts(
                self.pid_gains.as_ref(),
                self.impedance_params.as_ref(),
                self.filter_config.as_ref(),
                self.safety_limits.as_ref(),
            )
    }
}

impl Unknowns for crate::MultiAxisCommand {
    fn any_unknown(&self) -> bool {
        self.extra.keys().any(|k| k != STREAM)
            || self
                .coordination
                .as_ref()
                .is_some_and(|c| !c.extra.is_empty())
            || self.motors.iter().any(|a| {
                !a.extra.is_empty()
                    || any_in_parts(
                        a.pid_gains.as_ref(),
                        a.impedance_params.as_ref(),
                        a.filter_config.as_ref(),
                        a.safety_limits.as_ref(),
                    )
            })
    }
}

/// `s` as a JSON Pointer token.
fn token(s: &str) -> String {
    s.replace('~', "~0").replace('/', "~1")
}

/// The pointer to where the scan stands, `/a/0/b`.
fn pointer(stack: &[Frame<'_, '_>]) -> String {
    let mut p = String::new();
    for f in stack {
        match f {
            Frame::Object {
                key: Some((k, _)), ..
            } => {
                p.push('/');
                p.push_str(&token(k));
            }
            Frame::Array { index, .. } => {
                p.push('/');
                p.push_str(&index.to_string());
            }
            Frame::Object { key: None, .. } => {}
        }
    }
    p
}

/// The member of `names` nearest `key` (an edit or two away, or one of
/// them contains the other), when one is near enough to be meant.
fn nearest<'a>(key: &str, names: impl Iterator<Item = &'a String>) -> Option<&'a str> {
    let folded = key.to_ascii_lowercase();
    names
        .map(|n| {
            let d = strsim::damerau_levenshtein(&folded, n);
            let within = n.contains(folded.as_str()) || folded.contains(n.as_str());
            (if within { d.min(2) } else { d }, n)
        })
        .filter(|(d, n)| *d <= 2.max(n.len() / 4) && *d < n.len())
        .min_by_key(|(d, _)| *d)
        .map(|(_, n)| n.as_str())
}

/// Every member of `json` (valid JSON: the typed parse took it) that the
/// schema of `kind` does not name where it stands, in document order.
pub(crate) fn unknown_members(kind: MessageKind, json: &str) -> Vec<Violation> {
    let bytes = json.as_bytes();
    let mut out = Vec::new();
    let mut stack: Vec<Frame<'_, '_>> = Vec::new();
    // What the schema says of the value that starts next.
    let mut next: Option<&Known> = Some(known(kind));
    let mut i = 0;
    let mut found = 0usize;
    while let Some(&b) = bytes.get(i) {
        match b {
            b'{' => {
                stack.push(Frame::Object {
                    known: next,
                    key: None,
                });
                i += 1;
            }
            b'[' => {
                stack.push(Frame::Array {
                    known: next,
                    index: 0,
                });
                next = match stack.last() {
                    Some(Frame::Array { known, .. }) => known.and_then(|k| k.items.as_deref()),
                    _ => None,
                };
                i += 1;
            }
            b'}' | b']' => {
                stack.pop();
                i += 1;
            }
            b',' => {
                match stack.last_mut() {
                    Some(Frame::Array { known, index }) => {
                        *index += 1;
                        next = known.and_then(|k| k.items.as_deref());
                    }
                    Some(Frame::Object { key, .. }) => *key = None,
                    None => {}
                }
                i += 1;
            }
            b':' => {
                next = match stack.last() {
                    Some(Frame::Object {
                        key: Some((_, k)), ..
                    }) => *k,
                    _ => None,
                };
                i += 1;
            }
            b'"' => {
                // The string's end: the first quote not escaped.
                let start = i;
                let mut j = i + 1;
                let mut escaped = false;
                while let Some(&c) = bytes.get(j) {
                    if escaped {
                        escaped = false;
                    } else if c == b'\\' {
                        escaped = true;
                    } else if c == b'"' {
                        break;
                    }
                    j += 1;
                }
                let text = json.get(start..=j).unwrap_or_default();
                i = j + 1;
                let at_key = matches!(stack.last(), Some(Frame::Object { key: None, .. }));
                if !at_key {
                    continue; // a string value
                }
                let name: Cow<'_, str> = if text.contains('\\') {
                    Cow::Owned(serde_json::from_str::<String>(text).unwrap_or_default())
                } else {
                    Cow::Borrowed(
                        text.get(1..text.len().saturating_sub(1))
                            .unwrap_or_default(),
                    )
                };
                let Some(Frame::Object { known, .. }) = stack.last() else {
                    continue;
                };
                let known = *known;
                let child = match known.and_then(|k| k.members.as_ref()) {
                    // Anything goes here (or below an unknown member).
                    None => None,
                    Some(members) => match members.get(name.as_ref()) {
                        Some(k) => Some(k),
                        None => {
                            found += 1;
                            if found <= MAX_REPORTED {
                                let here = pointer(&stack);
                                out.push(Violation::new(
                                    format!("{here}/{}", token(shown(&name))),
                                    Rule::UnknownMember,
                                    unknown_message(kind, &name, members),
                                ));
                            }
                            None
                        }
                    },
                };
                if let Some(Frame::Object { key, .. }) = stack.last_mut() {
                    *key = Some((name, child));
                }
            }
            _ => i += 1,
        }
    }
    if found > MAX_REPORTED {
        out.push(Violation::new(
            "",
            Rule::UnknownMember,
            format!(
                "and {} more unknown members (the first {MAX_REPORTED} are listed)",
                found - MAX_REPORTED
            ),
        ));
    }
    out
}

/// Unknown members listed one by one at most; the rest are counted.
const MAX_REPORTED: usize = 16;

/// The longest name compared with the known ones, and shown whole: a
/// longer one is no typo of theirs (they are at most 32 bytes), and
/// comparing it would cost its length times theirs.
const MAX_NAME_COMPARED: usize = 64;

/// `name`, cut to [`MAX_NAME_COMPARED`] bytes (on a character boundary).
fn shown(name: &str) -> &str {
    let mut end = name.len().min(MAX_NAME_COMPARED);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    name.get(..end).unwrap_or_default()
}

/// What an unknown member's violation says: its name (cut when long), and
/// the known member meant when one is near.
fn unknown_message(kind: MessageKind, name: &str, members: &BTreeMap<String, Known>) -> String {
    let cut = if name.len() > MAX_NAME_COMPARED {
        format!(" (its first {MAX_NAME_COMPARED} bytes of {})", name.len())
    } else {
        String::new()
    };
    let hint = if name.len() > MAX_NAME_COMPARED {
        None
    } else {
        nearest(name, members.keys())
    }
    .map(|n| format!("; did you mean {n}?"))
    .unwrap_or_default();
    format!(
        "{:?}{cut} is not a member {kind} has here{hint} (motorwire takes unknown members only when told to: `Validator::lenient`, `--allow-unknown-members`, `validate --allow-unknown`)",
        shown(name)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn found(kind: MessageKind, json: &str) -> Vec<(String, String)> {
        unknown_members(kind, json)
            .into_iter()
            .map(|v| (v.pointer, v.message))
            .collect()
    }

    #[test]
    fn a_misspelled_member_is_found_with_the_member_meant() {
        let v = found(
            MessageKind::MotorCommand,
            r#"{"motor_id":"elbow","timestamp":1,"control_mode":"position","setpoint":20,"velocity_limt":5}"#,
        );
        assert_eq!(
            v,
            [(
                "/velocity_limt".to_owned(),
                r#""velocity_limt" is not a member motor-command has here; did you mean velocity_limit? (motorwire takes unknown members only when told to: `Validator::lenient`, `--allow-unknown-members`, `validate --allow-unknown`)"#.to_owned()
            )]
        );
    }

    #[test]
    fn nested_members_items_and_references_are_judged_where_they_stand() {
        let v = found(
            MessageKind::MultiAxisCommand,
            r#"{"command_id":"c","timestamp":1,"motors":[{"motor_id":"a","control_mode":"position","setpoint":1},{"motor_id":"b","control_mode":"position","setpoint":2,"safety_limits":{"max_positon":3},"timestamp":4}],"coordination":{"typ":"independent"},"metadata":{"anything":{"goes":[1]}}}"#,
        );
        let at: Vec<&str> = v.iter().map(|(p, _)| p.as_str()).collect();
        assert_eq!(
            at,
            [
                "/motors/1/safety_limits/max_positon",
                "/motors/1/timestamp",
                "/coordination/typ"
            ]
        );
        assert!(v[0].1.contains("did you mean max_position?"), "{}", v[0].1);
        assert!(v[2].1.contains("did you mean type?"), "{}", v[2].1);
        // Nothing near: no guess.
        let v = found(
            MessageKind::MotorCommand,
            r#"{"motor_id":"m","timestamp":1,"control_mode":"position","setpoint":1,"zzzzzz":{"velocity_limt":1}}"#,
        );
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(!v[0].1.contains("did you mean"), "{}", v[0].1);
    }

    #[test]
    fn escapes_strings_and_pointers_are_read_as_json_writes_them() {
        // A key spelled with an escape is the key; a string value holding
        // braces, colons and quotes is a value.
        let v = found(
            MessageKind::MotorCommand,
            r#"{"motor_id":"m:{\"x\":1}","timestamp":1,"control_mode":"position","setpoint":1,"a\/b~":2,"setp\u006fint":3}"#,
        );
        let at: Vec<&str> = v.iter().map(|(p, _)| p.as_str()).collect();
        assert_eq!(at, ["/a~1b~0"]);
        // Every kind's own example members are known.
        assert!(
            found(
                MessageKind::SafetyLimits,
                r#"{"motor_id":"m","position_limits":{"min":0,"max":1},"velocity_limits":{"max_velocity":1}}"#
            )
            .is_empty()
        );
    }

    /// The command types skip the scan when their typed parse kept no
    /// unknown member: that must be exactly when the scan finds none.
    #[test]
    fn the_typed_shortcut_agrees_with_the_scan_at_every_level() {
        let v = crate::Validator::new().deny_unknown_members(true);
        let multi = |axis: &str, top: &str| {
            format!(
                r#"{{"command_id":"c","timestamp":1,"motors":[{{"motor_id":"a","control_mode":"position","setpoint":1{axis}}}]{top}}}"#
            )
        };
        let cases = [
            (multi("", ""), vec![]),
            (multi(r#","timestamp":4"#, ""), vec!["/motors/0/timestamp"]),
            (
                multi(r#","pid_gains":{"kq":1}"#, ""),
                vec!["/motors/0/pid_gains/kq"],
            ),
            (
                multi(r#","impedance_params":{"stifness":1}"#, ""),
                vec!["/motors/0/impedance_params/stifness"],
            ),
            (
                multi(r#","filter_config":{"cutoff":1}"#, ""),
                vec!["/motors/0/filter_config/cutoff"],
            ),
            (
                multi(r#","safety_limits":{"max_pos":1}"#, ""),
                vec!["/motors/0/safety_limits/max_pos"],
            ),
            (
                multi("", r#","coordination":{"duration":1}"#),
                vec!["/coordination/duration"],
            ),
            (multi("", r#","sync":"independent""#), vec!["/sync"]),
            (
                multi(r#","metadata":{"x":1}"#, r#","metadata":{"y":{"z":1}}"#),
                vec![],
            ),
        ];
        for (doc, want) in cases {
            let r = v.validate(MessageKind::MultiAxisCommand, &doc);
            let got: Vec<&str> = r.violations.iter().map(|x| x.pointer.as_str()).collect();
            assert_eq!(got, want, "{doc}");
            let scanned: Vec<String> = unknown_members(MessageKind::MultiAxisCommand, &doc)
                .into_iter()
                .map(|x| x.pointer)
                .collect();
            assert_eq!(scanned, want, "{doc}");
        }
        let cmd = |more: &str| {
            format!(
                r#"{{"motor_id":"m","timestamp":1,"control_mode":"position","setpoint":1{more}}}"#
            )
        };
        for (more, want) in [
            ("", vec![]),
            (r#","pid_gains":{"kp":1,"kk":2}"#, vec!["/pid_gains/kk"]),
            (
                r#","impedance_params":{"dampng":1}"#,
                vec!["/impedance_params/dampng"],
            ),
            (
                r#","filter_config":{"ordr":1}"#,
                vec!["/filter_config/ordr"],
            ),
            (
                r#","safety_limits":{"emergency":false}"#,
                vec!["/safety_limits/emergency"],
            ),
            (r#","metadata":{"anything":1}"#, vec![]),
        ] {
            let doc = cmd(more);
            let r = v.validate(MessageKind::MotorCommand, &doc);
            let got: Vec<&str> = r.violations.iter().map(|x| x.pointer.as_str()).collect();
            assert_eq!(got, want, "{doc}");
        }
    }

    #[test]
    fn many_or_huge_unknown_members_cost_little_and_say_little() {
        // 8,000 short unknown members: 16 listed, the rest counted.
        let many: String = (0..8000).map(|i| format!(",\"k{i}\":0")).collect();
        let doc = format!(
            r#"{{"motor_id":"m","timestamp":1,"control_mode":"position","setpoint":1{many}}}"#
        );
        let v = unknown_members(MessageKind::MotorCommand, &doc);
        assert_eq!(v.len(), MAX_REPORTED + 1);
        assert_eq!(v[0].pointer, "/k0");
        assert_eq!(
            v[MAX_REPORTED].message,
            "and 7984 more unknown members (the first 16 are listed)"
        );
        // A 60,000-byte near miss: shown cut, compared with nothing.
        let key = format!("velocity_limit{}", "x".repeat(60_000));
        let doc = format!(
            r#"{{"motor_id":"m","timestamp":1,"control_mode":"position","setpoint":1,"{key}":1}}"#
        );
        let v = unknown_members(MessageKind::MotorCommand, &doc);
        assert_eq!(v.len(), 1);
        assert_eq!(v[0].pointer, format!("/{}", &key[..64]));
        assert!(
            v[0].message.starts_with(&format!(
                "{:?} (its first 64 bytes of 60014) is not a member motor-command has here (motorwire takes",
                &key[..64]
            )),
            "{}",
            v[0].message
        );
    }

    #[test]
    fn a_near_name_is_offered_and_a_far_one_is_not() {
        let names: Vec<String> = ["setpoint", "velocity_limit", "torque_limit", "motor_id"]
            .iter()
            .map(|s| (*s).to_owned())
            .collect();
        assert_eq!(nearest("setpiont", names.iter()), Some("setpoint"));
        assert_eq!(
            nearest("Velocity_Limit", names.iter()),
            Some("velocity_limit")
        );
        assert_eq!(nearest("motor", names.iter()), Some("motor_id"));
        assert_eq!(nearest("torq_limit", names.iter()), Some("torque_limit"));
        assert_eq!(nearest("colour", names.iter()), None);
        assert_eq!(nearest("x", names.iter()), None);
    }
}
