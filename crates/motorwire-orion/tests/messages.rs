//! Orion messages: the document's examples, every error, both feedback key
//! forms, clamping, and hostile input.
#![allow(clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

use motorwire_orion::*;
use proptest::prelude::*;

fn err(text: &str) -> Error {
    Input::parse(text).unwrap_err()
}

#[test]
fn the_documents_examples_parse_and_round_trip() {
    let input = r#"{"ID": 32, "MODE": 1, "DATA": {"TRM": 200, "LAA": 1, "UAA": 1, "AEM": 400}}"#;
    let Input::DirectControl(v) = Input::parse(input).unwrap() else {
        panic!()
    };
    assert_eq!(
        v,
        MotorValues::new()
            .with(Motor::Turntable, 200.0)
            .with(Motor::LowerArmActuator, 1.0)
            .with(Motor::UpperArmActuator, 1.0)
            .with(Motor::ArmExtension, 400.0)
    );
    assert_eq!(
        Input::DirectControl(v).to_json(),
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":200,"LAA":1,"UAA":1,"AEM":400}}"#
    );
    assert_eq!(
        Input::parse(r#"{"ID": 32, "MODE": 2, "DATA": 3}"#).unwrap(),
        Input::Command(CommandNumber(3))
    );
    let output = r#"{"ID": 32, "MODE": 1, "DATA": {"TRM": [200, 65, 0], "LAA": [1, 50, 0], "UAA": [1, 45, 0], "AEM": [400, 35, 0]}}"#;
    let Output::DirectControl(fb) = Output::parse(output).unwrap() else {
        panic!()
    };
    assert_eq!(
        fb.get(Motor::UpperArmActuator),
        Some(MotorFeedback {
            value: 1.0,
            current: 45.0,
            error: 0
        })
    );
    assert_eq!(fb.get(Motor::GrasperVertical), None);
    assert_eq!(
        Output::DirectControl(fb).to_json(FeedbackKeys::Example),
        r#"{"ID":32,"MODE":1,"DATA":{"TRM":[200,65,0],"LAA":[1,50,0],"UAA":[1,45,0],"AEM":[400,35,0]}}"#
    );
    assert_eq!(
        Output::DirectControl(fb).to_json(FeedbackKeys::Table),
        r#"{"ID":32,"MODE":1,"DATA":{"TRMF":[200,65,0],"LAAF":[1,50,0],"UAAF":[1,45,0],"AEMF":[400,35,0]}}"#
    );
    assert_eq!(FeedbackKeys::default(), FeedbackKeys::Table);
    assert_eq!(
        Output::parse(r#"{"ID": 32, "MODE": 2, "DATA": {"CMDF": 1}}"#).unwrap(),
        Output::Command { succeeded: true }
    );
    assert_eq!(Output::parse(r#"{"ID": 32}"#).unwrap(), Output::Beacon);
}

#[test]
fn every_parse_error_is_typed_and_says_what() {
    let cases: Vec<(&str, Error, &str)> = vec![
        (
            r#"{"ID":32,"MODE":1"#,
            Error::Json {
                message: "EOF while parsing an object at line 1 column 17".into(),
            },
            "not valid JSON: EOF while parsing an object at line 1 column 17",
        ),
        (
            "[32]",
            Error::NotAnObject { got: "an array" },
            "an Orion message is a JSON object, not an array",
        ),
        (
            r#"{"ID":33,"MODE":1,"DATA":{}}"#,
            Error::WrongControllerId {
                got: 33,
                group: Some("manipulator controllers' 32-63"),
            },
            "ID 33 is not the arm controller's 32 (33 is in the manipulator controllers' 32-63 range)",
        ),
        (
            r#"{"ID":300,"MODE":1,"DATA":{}}"#,
            Error::WrongControllerId {
                got: 300,
                group: None,
            },
            "ID 300 is not the arm controller's 32",
        ),
        (
            r#"{"ID":"32","MODE":1,"DATA":{}}"#,
            Error::WrongType {
                key: "ID".into(),
                expected: "a non-negative integer",
                got: r#""32""#.into(),
            },
            r#"ID must be a non-negative integer, not "32""#,
        ),
        (
            r#"{"MODE":1,"DATA":{}}"#,
            Error::MissingKey {
                key: "ID",
                within: "the message",
            },
            r#"the message has no "ID" key"#,
        ),
        (
            r#"{"ID":32,"MODE":0,"DATA":1}"#,
            Error::InvalidMode,
            "MODE 0 is the document's invalid mode; use 1 (direct control) or 2 (command)",
        ),
        (
            r#"{"ID":32,"MODE":3,"DATA":1}"#,
            Error::ModeOutOfRange { got: 3 },
            "MODE 3 is outside [0, 2]",
        ),
        (
            r#"{"ID":32,"MODE":-1,"DATA":1}"#,
            Error::WrongType {
                key: "MODE".into(),
                expected: "1 or 2",
                got: "-1".into(),
            },
            "MODE must be 1 or 2, not -1",
        ),
        (
            r#"{"ID":32,"MODE":1.5,"DATA":1}"#,
            Error::WrongType {
                key: "MODE".into(),
                expected: "a non-negative integer",
                got: "1.5".into(),
            },
            "MODE must be a non-negative integer, not 1.5",
        ),
        (
            r#"{"ID":32,"MODE":1}"#,
            Error::MissingKey {
                key: "DATA",
                within: "the message",
            },
            r#"the message has no "DATA" key"#,
        ),
        (
            r#"{"ID":32}"#,
            Error::MissingKey {
                key: "MODE",
                within: "the message",
            },
            r#"the message has no "MODE" key"#,
        ),
        (
            r#"{"ID":32,"MODE":1,"DATA":{"XYZ":1}}"#,
            Error::UnknownKey {
                key: "XYZ".into(),
                within: "DATA",
                hint: None,
            },
            r#"unknown key "XYZ" in DATA"#,
        ),
        (
            r#"{"ID":32,"MODE":1,"DATA":{"TRMF":1}}"#,
            Error::UnknownKey {
                key: "TRMF".into(),
                within: "DATA",
                hint: Some("a feedback key; commands use the key without F"),
            },
            r#"unknown key "TRMF" in DATA (a feedback key; commands use the key without F)"#,
        ),
        (
            r#"{"ID":32,"MODE":1,"DATA":{},"TRM":1}"#,
            Error::UnknownKey {
                key: "TRM".into(),
                within: "the message",
                hint: Some("motor keys go inside DATA"),
            },
            r#"unknown key "TRM" in the message (motor keys go inside DATA)"#,
        ),
        (
            r#"{"ID":32,"MODE":1,"DATA":{"TRM":"fast"}}"#,
            Error::WrongType {
                key: "TRM".into(),
                expected: "a number",
                got: r#""fast""#.into(),
            },
            r#"TRM must be a number, not "fast""#,
        ),
        (
            r#"{"ID":32,"MODE":1,"DATA":{"LAA":true}}"#,
            Error::WrongType {
                key: "LAA".into(),
                expected: "a number",
                got: "true".into(),
            },
            "LAA must be a number, not true",
        ),
        (
            r#"{"ID":32,"MODE":1,"DATA":5}"#,
            Error::WrongType {
                key: "DATA".into(),
                expected: "an object of motor values",
                got: "5".into(),
            },
            "DATA must be an object of motor values, not 5",
        ),
        (
            r#"{"ID":32,"MODE":2,"DATA":{"CMD":1}}"#,
            Error::WrongType {
                key: "DATA".into(),
                expected: "an integer command number",
                got: r#"{"CMD":1}"#.into(),
            },
            r#"DATA must be an integer command number, not {"CMD":1}"#,
        ),
        (
            r#"{"ID":32,"MODE":2,"DATA":2.5}"#,
            Error::WrongType {
                key: "DATA".into(),
                expected: "an integer command number",
                got: "2.5".into(),
            },
            "DATA must be an integer command number, not 2.5",
        ),
        (
            r#"{"ID":32,"MODE":2,"DATA":18446744073709551615}"#,
            Error::CommandOutOfRange {
                got: "18446744073709551615".into(),
            },
            "command number 18446744073709551615 is outside the 64-bit integer range",
        ),
        (
            r#"{"ID":32,"MODE":1,"DATA":{"TRM":1,"TRM":2}}"#,
            Error::DuplicateKey {
                key: "TRM".into(),
                within: "DATA",
            },
            r#"the key "TRM" appears more than once in DATA"#,
        ),
        (
            r#"{"ID":32,"ID":32,"MODE":2,"DATA":1}"#,
            Error::DuplicateKey {
                key: "ID".into(),
                within: "the message",
            },
            r#"the key "ID" appears more than once in the message"#,
        ),
    ];
    for (text, want, message) in cases {
        let got = err(text);
        assert_eq!(got, want, "{text}");
        assert_eq!(got.to_string(), message, "{text}");
    }
}

#[test]
fn hostile_json_is_an_error_not_a_panic() {
    // Nesting beyond serde_json's limit of 128.
    let deep = format!(
        r#"{{"ID":32,"MODE":1,"DATA":{}1{}}}"#,
        "[".repeat(10_000),
        "]".repeat(10_000)
    );
    assert!(matches!(err(&deep), Error::Json { message } if message.contains("recursion limit")));
    // A number beyond f64.
    assert!(matches!(
        err(r#"{"ID":32,"MODE":1,"DATA":{"TRM":1e400}}"#),
        Error::Json { message } if message.contains("number out of range")
    ));
    // NaN is not JSON.
    assert!(matches!(
        err(r#"{"ID":32,"MODE":1,"DATA":{"TRM":NaN}}"#),
        Error::Json { .. }
    ));
    assert!(matches!(err(""), Error::Json { .. }));
    assert!(matches!(
        err(r#"{"ID":32,"MODE":2,"DATA":1} trailing"#),
        Error::Json { .. }
    ));
}

#[test]
fn command_numbers_other_than_1_to_3_parse_and_are_not_commands() {
    for (n, command) in [
        (0, None),
        (1, Some(ArmCommand::Stop)),
        (2, Some(ArmCommand::Fold)),
        (3, Some(ArmCommand::Unfold)),
        (4, None),
        (-7, None),
    ] {
        let input = Input::parse(&format!(r#"{{"ID":32,"MODE":2,"DATA":{n}}}"#)).unwrap();
        assert_eq!(input, Input::Command(CommandNumber(n)));
        assert_eq!(CommandNumber(n).command(), command);
    }
}

#[test]
fn feedback_parses_in_both_key_forms_and_refuses_malformed_arrays() {
    let table = r#"{"ID":32,"MODE":1,"DATA":{"GHSF":[-12.5,10,1]}}"#;
    let Output::DirectControl(fb) = Output::parse(table).unwrap() else {
        panic!()
    };
    assert_eq!(
        fb.get(Motor::GrasperHorizontalServo),
        Some(MotorFeedback {
            value: -12.5,
            current: 10.0,
            error: 1
        })
    );
    assert_eq!(
        Output::parse(r#"{"ID":32,"MODE":1,"DATA":{"TRM":[1,2,0],"TRMF":[1,2,0]}}"#),
        Err(Error::DuplicateKey {
            key: "TRMF".into(),
            within: "DATA"
        })
    );
    for bad in [
        "[1,2]",
        "[1,2,3,4]",
        r#"[1,"2",0]"#,
        "[1,2,0.5]",
        "[1,2,-1]",
        "7",
    ] {
        let text = format!(r#"{{"ID":32,"MODE":1,"DATA":{{"AEMF":{bad}}}}}"#);
        assert_eq!(
            Output::parse(&text),
            Err(Error::BadFeedback {
                key: "AEMF".into(),
                got: bad.into()
            }),
            "{bad}"
        );
    }
    assert_eq!(
        Output::parse(r#"{"ID":32,"MODE":2,"DATA":{"CMDF":2}}"#),
        Err(Error::BadCommandFeedback { got: "2".into() })
    );
    assert_eq!(
        Output::parse(r#"{"ID":32,"MODE":2,"DATA":{}}"#),
        Err(Error::MissingKey {
            key: "CMDF",
            within: "DATA"
        })
    );
}

#[test]
fn clamping_is_reported_for_every_motor_out_of_range() {
    let v = MotorValues::new()
        .with(Motor::Turntable, 401.0)
        .with(Motor::LowerArmActuator, -1.5)
        .with(Motor::UpperArmActuator, 1.0)
        .with(Motor::GrasperHorizontalServo, 720.0);
    let (clamped, clamps) = v.clamped();
    assert_eq!(clamped.get(Motor::UpperArmActuator), Some(1.0));
    assert_eq!(
        clamps,
        vec![
            Clamp {
                motor: Motor::Turntable,
                requested: 401.0,
                applied: 400.0
            },
            Clamp {
                motor: Motor::LowerArmActuator,
                requested: -1.5,
                applied: -1.0
            },
            Clamp {
                motor: Motor::GrasperHorizontalServo,
                requested: 720.0,
                applied: 180.0
            },
        ]
    );
    assert_eq!(
        clamps[2].to_string(),
        "GHS 720 is outside [-180, 180]; clamped to 180"
    );
}

#[test]
fn motor_keys_names_and_ranges() {
    let keys: Vec<&str> = Motor::ALL.iter().map(|m| m.key()).collect();
    assert_eq!(keys, ["TRM", "LAA", "UAA", "AEM", "GVM", "GRM", "GHS"]);
    for m in Motor::ALL {
        assert_eq!(Motor::from_key(m.key()), Some(m));
        assert_eq!(Motor::from_feedback_key(m.feedback_key()), Some(m));
        assert_eq!(Motor::from_name(m.name()), Some(m));
        assert_eq!(m.feedback_key(), format!("{}F", m.key()));
    }
    assert_eq!(Motor::GrasperHorizontalServo.range(), (-180.0, 180.0));
    assert_eq!(Motor::LowerArmActuator.range(), (-1.0, 1.0));
    assert_eq!(Motor::GrasperRotation.range(), (-400.0, 400.0));
}

proptest! {
    #[test]
    fn arbitrary_text_never_panics(text in ".{0,200}") {
        let _ = Input::parse(&text);
        let _ = Output::parse(&text);
    }

    #[test]
    fn arbitrary_direct_control_round_trips(values in proptest::collection::vec(proptest::option::of(-1e6f64..1e6), 7)) {
        let mut v = MotorValues::new();
        for (m, x) in Motor::ALL.into_iter().zip(&values) {
            if let Some(x) = x {
                v.set(m, *x);
            }
        }
        let text = Input::DirectControl(v).to_json();
        prop_assert_eq!(Input::parse(&text).unwrap(), Input::DirectControl(v));
        let (clamped, clamps) = v.clamped();
        for (m, x) in clamped.iter() {
            let (lo, hi) = m.range();
            prop_assert!(lo <= x && x <= hi);
        }
        prop_assert_eq!(clamps.len(), v.iter().filter(|(m, x)| *x < m.range().0 || *x > m.range().1).count());
    }
}
