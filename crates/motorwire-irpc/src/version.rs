use core::fmt;
use core::str::FromStr;

/// An iRPC wire version. Versions are chosen explicitly: the public
/// implementation inserted payloads before `Ack` from one release to the
/// next, so the same tag means different things in different versions and no
/// version is "compatible" with another.
///
/// ```
/// use motorwire_irpc::{PayloadKind, WireVersion};
/// assert_eq!(WireVersion::V2_0.tag_of(PayloadKind::Ack), Some(8));
/// assert_eq!(WireVersion::V2_1.tag_of(PayloadKind::Ack), Some(18));
/// assert_eq!(WireVersion::V1.tag_of(PayloadKind::SetTargetV2), None);
/// assert_eq!("v2.2".parse::<WireVersion>(), Ok(WireVersion::V2_2));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum WireVersion {
    /// v1: lifecycle, `SetTarget`, encoder and status, Ack/Nack, ArmReady.
    V1,
    /// v2.0, the document's: adds `SetTargetV2` before `Encoder`.
    V2_0,
    /// v2.1: adds telemetry streaming, adaptive control and calibration before `Ack`.
    V2_1,
    /// v2.2: adds power management, emergency stop and fault history before `Ack`.
    V2_2,
}

/// The payload variants across every wire version.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[allow(missing_docs)] // each is documented on `Payload`
pub enum PayloadKind {
    SetTarget,
    Configure,
    Activate,
    Deactivate,
    Reset,
    SetTargetV2,
    Encoder,
    JointStatus,
    TelemetryStream,
    ConfigureTelemetry,
    RequestTelemetry,
    ConfigureAdaptive,
    RequestAdaptiveStatus,
    AdaptiveStatus,
    StartCalibration,
    StopCalibration,
    CalibrationStatus,
    CalibrationResult,
    PowerMetrics,
    EmergencyStop,
    ConfigurePower,
    RequestPowerConfig,
    PowerConfigResponse,
    RequestFaultHistory,
    FaultHistory,
    Ack,
    Nack,
    ArmReady,
}

use PayloadKind as K;

const V1: &[PayloadKind] = &[
    K::SetTarget,
    K::Configure,
    K::Activate,
    K::Deactivate,
    K::Reset,
    K::Encoder,
    K::JointStatus,
    K::Ack,
    K::Nack,
    K::ArmReady,
];

const V2_0: &[PayloadKind] = &[
    K::SetTarget,
    K::Configure,
    K::Activate,
    K::Deactivate,
    K::Reset,
    K::SetTargetV2,
    K::Encoder,
    K::JointStatus,
    K::Ack,
    K::Nack,
    K::ArmReady,
];

const V2_1: &[PayloadKind] = &[
    K::SetTarget,
    K::Configure,
    K::Activate,
    K::Deactivate,
    K::Reset,
    K::SetTargetV2,
    K::Encoder,
    K::JointStatus,
    K::TelemetryStream,
    K::ConfigureTelemetry,
    K::RequestTelemetry,
    K::ConfigureAdaptive,
    K::RequestAdaptiveStatus,
    K::AdaptiveStatus,
    K::StartCalibration,
    K::StopCalibration,
    K::CalibrationStatus,
    K::CalibrationResult,
    K::Ack,
    K::Nack,
    K::ArmReady,
];

const V2_2: &[PayloadKind] = &[
    K::SetTarget,
    K::Configure,
    K::Activate,
    K::Deactivate,
    K::Reset,
    K::SetTargetV2,
    K::Encoder,
    K::JointStatus,
    K::TelemetryStream,
    K::ConfigureTelemetry,
    K::RequestTelemetry,
    K::ConfigureAdaptive,
    K::RequestAdaptiveStatus,
    K::AdaptiveStatus,
    K::StartCalibration,
    K::StopCalibration,
    K::CalibrationStatus,
    K::CalibrationResult,
    K::PowerMetrics,
    K::EmergencyStop,
    K::ConfigurePower,
    K::RequestPowerConfig,
    K::PowerConfigResponse,
    K::RequestFaultHistory,
    K::FaultHistory,
    K::Ack,
    K::Nack,
    K::ArmReady,
];

const KINDS: usize = 28;
const ABSENT: u8 = u8::MAX;

/// The inverse of a version's list: tag by kind. Evaluated at compile time,
/// where an index out of bounds is a compile error, not a panic.
#[allow(clippy::indexing_slicing, clippy::cast_possible_truncation)]
const fn tags(list: &[PayloadKind]) -> [u8; KINDS] {
    let mut out = [ABSENT; KINDS];
    let mut i = 0;
    while i < list.len() {
        out[list[i] as usize] = i as u8;
        i += 1;
    }
    out
}

const TAGS_V1: [u8; KINDS] = tags(V1);
const TAGS_V2_0: [u8; KINDS] = tags(V2_0);
const TAGS_V2_1: [u8; KINDS] = tags(V2_1);
const TAGS_V2_2: [u8; KINDS] = tags(V2_2);

impl WireVersion {
    /// Every version, oldest first.
    pub const ALL: [WireVersion; 4] = [Self::V1, Self::V2_0, Self::V2_1, Self::V2_2];

    /// The payloads of this version, in tag order from 0.
    pub const fn payloads(self) -> &'static [PayloadKind] {
        match self {
            Self::V1 => V1,
            Self::V2_0 => V2_0,
            Self::V2_1 => V2_1,
            Self::V2_2 => V2_2,
        }
    }

    /// The tag of `kind` in this version, or `None` if it does not exist here.
    #[inline]
    pub fn tag_of(self, kind: PayloadKind) -> Option<u32> {
        let table = match self {
            Self::V1 => &TAGS_V1,
            Self::V2_0 => &TAGS_V2_0,
            Self::V2_1 => &TAGS_V2_1,
            Self::V2_2 => &TAGS_V2_2,
        };
        table
            .get(kind as usize)
            .copied()
            .filter(|t| *t != ABSENT)
            .map(u32::from)
    }

    /// The payload with tag `tag` in this version.
    #[inline]
    pub fn kind_of(self, tag: u32) -> Option<PayloadKind> {
        self.payloads().get(usize::try_from(tag).ok()?).copied()
    }

    /// Whether `LifecycleState` has the `Calibrating` state (v2.1 on).
    pub const fn has_calibrating_state(self) -> bool {
        matches!(self, Self::V2_1 | Self::V2_2)
    }

    /// The name used on the command line: `v1`, `v2.0`, `v2.1`, `v2.2`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::V1 => "v1",
            Self::V2_0 => "v2.0",
            Self::V2_1 => "v2.1",
            Self::V2_2 => "v2.2",
        }
    }
}

impl fmt::Display for WireVersion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is not `v1`, `v2.0`, `v2.1` or `v2.2`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnknownWireVersion;

impl fmt::Display for UnknownWireVersion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("unknown iRPC wire version; expected v1, v2.0, v2.1 or v2.2")
    }
}

impl core::error::Error for UnknownWireVersion {}

impl FromStr for WireVersion {
    type Err = UnknownWireVersion;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or(UnknownWireVersion)
    }
}

impl PayloadKind {
    /// The payload's name, as in the JSON form.
    pub const fn name(self) -> &'static str {
        match self {
            K::SetTarget => "SetTarget",
            K::Configure => "Configure",
            K::Activate => "Activate",
            K::Deactivate => "Deactivate",
            K::Reset => "Reset",
            K::SetTargetV2 => "SetTargetV2",
            K::Encoder => "Encoder",
            K::JointStatus => "JointStatus",
            K::TelemetryStream => "TelemetryStream",
            K::ConfigureTelemetry => "ConfigureTelemetry",
            K::RequestTelemetry => "RequestTelemetry",
            K::ConfigureAdaptive => "ConfigureAdaptive",
            K::RequestAdaptiveStatus => "RequestAdaptiveStatus",
            K::AdaptiveStatus => "AdaptiveStatus",
            K::StartCalibration => "StartCalibration",
            K::StopCalibration => "StopCalibration",
            K::CalibrationStatus => "CalibrationStatus",
            K::CalibrationResult => "CalibrationResult",
            K::PowerMetrics => "PowerMetrics",
            K::EmergencyStop => "EmergencyStop",
            K::ConfigurePower => "ConfigurePower",
            K::RequestPowerConfig => "RequestPowerConfig",
            K::PowerConfigResponse => "PowerConfigResponse",
            K::RequestFaultHistory => "RequestFaultHistory",
            K::FaultHistory => "FaultHistory",
            K::Ack => "Ack",
            K::Nack => "Nack",
            K::ArmReady => "ArmReady",
        }
    }
}

impl fmt::Display for PayloadKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_appears_in_v2_2_and_tags_invert() {
        assert_eq!(V2_2.len(), KINDS);
        for v in WireVersion::ALL {
            for (tag, kind) in v.payloads().iter().enumerate() {
                assert_eq!(v.tag_of(*kind), Some(tag as u32));
                assert_eq!(v.kind_of(tag as u32), Some(*kind));
            }
            assert_eq!(v.kind_of(v.payloads().len() as u32), None);
            assert_eq!(v.kind_of(u32::MAX), None);
        }
    }

    #[test]
    fn the_documented_tags() {
        use WireVersion::*;
        assert_eq!(V1.payloads().len(), 10);
        assert_eq!(V2_0.payloads().len(), 11);
        assert_eq!(V2_1.payloads().len(), 21);
        assert_eq!(V2_2.payloads().len(), 28);
        assert_eq!(V2_0.tag_of(K::SetTargetV2), Some(5));
        assert_eq!(V2_0.tag_of(K::ArmReady), Some(10));
        assert_eq!(V2_1.tag_of(K::ArmReady), Some(20));
        assert_eq!(V2_2.tag_of(K::Ack), Some(25));
        assert_eq!(V1.tag_of(K::Ack), Some(7));
        assert_eq!(V2_1.tag_of(K::PowerMetrics), None);
    }
}
