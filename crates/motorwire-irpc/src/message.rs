//! `Header`, `Payload`, `Message`, and CAN-FD framing.

use crate::payload::*;
use crate::wire::{Counter, Out, Reader, SliceWriter, Stop, Wire, put_varint, wire_struct};
use crate::{Error, PayloadKind, WireVersion};

/// The largest CAN-FD frame payload.
pub const MAX_FRAME_LEN: usize = 64;

/// The payload lengths a CAN-FD frame can have.
pub const CAN_FD_LENGTHS: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

/// The smallest CAN-FD frame length that holds `len` bytes, or `None` above 64.
///
/// ```
/// use motorwire_irpc::can_fd_len;
/// assert_eq!(can_fd_len(5), Some(5));
/// assert_eq!(can_fd_len(37), Some(48));
/// assert_eq!(can_fd_len(65), None);
/// ```
pub fn can_fd_len(len: usize) -> Option<usize> {
    CAN_FD_LENGTHS.into_iter().find(|l| *l >= len)
}

wire_struct! {
    /// Who sends to whom, and the message's id for Ack/Nack matching.
    /// Three varints: 3 to 11 bytes.
    pub struct Header as "header" {
        /// Sender node id (0x0000 is the arm).
        source_id: u16,
        /// Receiver node id (0x0000 and 0xFFFF are broadcast).
        target_id: u16,
        /// Message id; Ack and Nack carry it back.
        msg_id: u32,
    }
}

impl Header {
    /// Decodes only the header at the start of `bytes`, returning it and the
    /// number of bytes it took. A receiver uses it to answer a message whose
    /// payload it refuses (a non-finite float, an unknown tag) with a `Nack`
    /// carrying the right `msg_id`.
    ///
    /// ```
    /// use motorwire_irpc::{Error, Header, Message, WireVersion};
    /// // SetTarget whose target_angle is NaN: the message is refused, its header is not.
    /// let bytes = [0x00, 0x10, 0x05, 0x00, 0x00, 0x00, 0xc0, 0x7f, 0x00, 0x00, 0x16, 0x43];
    /// assert!(matches!(Message::decode(WireVersion::V2_0, &bytes), Err(Error::NonFinite { .. })));
    /// let (header, used) = Header::decode_prefix(WireVersion::V2_0, &bytes)?;
    /// assert_eq!(header, Header { source_id: 0, target_id: 0x10, msg_id: 5 });
    /// assert_eq!(used, 3);
    /// # Ok::<(), motorwire_irpc::Error>(())
    /// ```
    ///
    /// # Errors
    /// A truncated or malformed varint, naming the field and offset.
    pub fn decode_prefix(v: WireVersion, bytes: &[u8]) -> Result<(Self, usize), Error> {
        let mut r = Reader::new(bytes);
        match Self::take(&mut r, "header", v) {
            Ok(h) => Ok((h, r.position())),
            Err(Stop { .. }) => Err(r.into_error()),
        }
    }
}

/// The payload of an iRPC message: every variant of every wire version.
/// Which ones exist, and their tags, depend on the [`WireVersion`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
#[allow(clippy::large_enum_variant)]
pub enum Payload {
    /// v1 motion command.
    SetTarget(SetTargetPayload),
    /// Lifecycle: configure.
    Configure,
    /// Lifecycle: activate.
    Activate,
    /// Lifecycle: deactivate.
    Deactivate,
    /// Lifecycle: reset.
    Reset,
    /// v2 motion command with a motion profile (v2.0 on).
    SetTargetV2(SetTargetPayloadV2),
    /// Encoder reading.
    Encoder(EncoderTelemetry),
    /// Lifecycle state and error code.
    JointStatus {
        /// The state.
        state: LifecycleState,
        /// The error code (0 = none).
        error_code: u16,
    },
    /// High-rate telemetry (v2.1 on).
    TelemetryStream(TelemetryStream),
    /// Telemetry configuration (v2.1 on).
    ConfigureTelemetry(ConfigureTelemetryPayload),
    /// Ask for one telemetry sample (v2.1 on).
    RequestTelemetry,
    /// Adaptive control configuration (v2.1 on).
    ConfigureAdaptive(ConfigureAdaptivePayload),
    /// Ask for the adaptive status (v2.1 on).
    RequestAdaptiveStatus,
    /// Adaptive control status (v2.1 on).
    AdaptiveStatus(AdaptiveStatusPayload),
    /// Start calibrating (v2.1 on).
    StartCalibration(CalibrationRequest),
    /// Stop calibrating (v2.1 on).
    StopCalibration,
    /// Calibration progress (v2.1 on).
    CalibrationStatus(CalibrationStatus),
    /// Calibration result (v2.1 on).
    CalibrationResult(CalibrationResult),
    /// Power metrics (v2.2).
    PowerMetrics(PowerMetrics),
    /// Emergency stop report (v2.2).
    EmergencyStop(EmergencyStop),
    /// Set the power configuration (v2.2).
    ConfigurePower(PowerConfig),
    /// Ask for the power configuration (v2.2).
    RequestPowerConfig,
    /// The power configuration (v2.2).
    PowerConfigResponse(PowerConfig),
    /// Ask for the fault history (v2.2).
    RequestFaultHistory,
    /// The fault history (v2.2).
    FaultHistory(FaultHistory),
    /// The message with this id was accepted.
    Ack(u32),
    /// The message with this id was refused.
    Nack {
        /// Its msg_id.
        id: u32,
        /// Why (1 configure in the wrong state, 2 activate, 3 deactivate,
        /// 4 set target, 255 unknown payload).
        error: u16,
    },
    /// The arm is ready (broadcast).
    ArmReady,
}

impl Payload {
    /// Which variant this is.
    pub const fn kind(&self) -> PayloadKind {
        match self {
            Self::SetTarget(_) => PayloadKind::SetTarget,
            Self::Configure => PayloadKind::Configure,
            Self::Activate => PayloadKind::Activate,
            Self::Deactivate => PayloadKind::Deactivate,
            Self::Reset => PayloadKind::Reset,
            Self::SetTargetV2(_) => PayloadKind::SetTargetV2,
            Self::Encoder(_) => PayloadKind::Encoder,
            Self::JointStatus { .. } => PayloadKind::JointStatus,
            Self::TelemetryStream(_) => PayloadKind::TelemetryStream,
            Self::ConfigureTelemetry(_) => PayloadKind::ConfigureTelemetry,
            Self::RequestTelemetry => PayloadKind::RequestTelemetry,
            Self::ConfigureAdaptive(_) => PayloadKind::ConfigureAdaptive,
            Self::RequestAdaptiveStatus => PayloadKind::RequestAdaptiveStatus,
            Self::AdaptiveStatus(_) => PayloadKind::AdaptiveStatus,
            Self::StartCalibration(_) => PayloadKind::StartCalibration,
            Self::StopCalibration => PayloadKind::StopCalibration,
            Self::CalibrationStatus(_) => PayloadKind::CalibrationStatus,
            Self::CalibrationResult(_) => PayloadKind::CalibrationResult,
            Self::PowerMetrics(_) => PayloadKind::PowerMetrics,
            Self::EmergencyStop(_) => PayloadKind::EmergencyStop,
            Self::ConfigurePower(_) => PayloadKind::ConfigurePower,
            Self::RequestPowerConfig => PayloadKind::RequestPowerConfig,
            Self::PowerConfigResponse(_) => PayloadKind::PowerConfigResponse,
            Self::RequestFaultHistory => PayloadKind::RequestFaultHistory,
            Self::FaultHistory(_) => PayloadKind::FaultHistory,
            Self::Ack(_) => PayloadKind::Ack,
            Self::Nack { .. } => PayloadKind::Nack,
            Self::ArmReady => PayloadKind::ArmReady,
        }
    }

    fn put<O: Out>(&self, o: &mut O, v: WireVersion) -> Result<(), Stop> {
        let kind = self.kind();
        let Some(tag) = v.tag_of(kind) else {
            return Err(o.fail(Error::PayloadNotInVersion {
                payload: kind,
                version: v,
            }));
        };
        put_varint(o, u64::from(tag))?;
        match self {
            Self::SetTarget(p) => p.put(o, "SetTarget", v),
            Self::SetTargetV2(p) => p.put(o, "SetTargetV2", v),
            Self::Encoder(p) => p.put(o, "Encoder", v),
            Self::JointStatus { state, error_code } => {
                state.put(o, "JointStatus.state", v)?;
                error_code.put(o, "JointStatus.error_code", v)
            }
            Self::TelemetryStream(p) => p.put(o, "TelemetryStream", v),
            Self::ConfigureTelemetry(p) => p.put(o, "ConfigureTelemetry", v),
            Self::ConfigureAdaptive(p) => p.put(o, "ConfigureAdaptive", v),
            Self::AdaptiveStatus(p) => p.put(o, "AdaptiveStatus", v),
            Self::StartCalibration(p) => p.put(o, "StartCalibration", v),
            Self::CalibrationStatus(p) => p.put(o, "CalibrationStatus", v),
            Self::CalibrationResult(p) => p.put(o, "CalibrationResult", v),
            Self::PowerMetrics(p) => p.put(o, "PowerMetrics", v),
            Self::EmergencyStop(p) => p.put(o, "EmergencyStop", v),
            Self::ConfigurePower(p) | Self::PowerConfigResponse(p) => p.put(o, "PowerConfig", v),
            Self::FaultHistory(p) => p.put(o, "FaultHistory", v),
            Self::Ack(id) => id.put(o, "Ack", v),
            Self::Nack { id, error } => {
                id.put(o, "Nack.id", v)?;
                error.put(o, "Nack.error", v)
            }
            Self::Configure
            | Self::Activate
            | Self::Deactivate
            | Self::Reset
            | Self::RequestTelemetry
            | Self::RequestAdaptiveStatus
            | Self::StopCalibration
            | Self::RequestPowerConfig
            | Self::RequestFaultHistory
            | Self::ArmReady => Ok(()),
        }
    }

    #[inline]
    fn take(r: &mut Reader<'_>, v: WireVersion) -> Result<Self, Stop> {
        let offset = r.position();
        let raw = r.varint("payload", 5, u64::from(u32::MAX))?;
        let tag = u32::try_from(raw).unwrap_or(u32::MAX);
        let Some(kind) = v.kind_of(tag) else {
            return Err(r.fail(Error::UnknownTag {
                tag,
                version: v,
                offset,
            }));
        };
        Ok(match kind {
            PayloadKind::SetTarget => Self::SetTarget(Wire::take(r, "SetTarget", v)?),
            PayloadKind::Configure => Self::Configure,
            PayloadKind::Activate => Self::Activate,
            PayloadKind::Deactivate => Self::Deactivate,
            PayloadKind::Reset => Self::Reset,
            PayloadKind::SetTargetV2 => Self::SetTargetV2(Wire::take(r, "SetTargetV2", v)?),
            PayloadKind::Encoder => Self::Encoder(Wire::take(r, "Encoder", v)?),
            PayloadKind::JointStatus => Self::JointStatus {
                state: Wire::take(r, "JointStatus.state", v)?,
                error_code: Wire::take(r, "JointStatus.error_code", v)?,
            },
            PayloadKind::TelemetryStream => {
                Self::TelemetryStream(Wire::take(r, "TelemetryStream", v)?)
            }
            PayloadKind::ConfigureTelemetry => {
                Self::ConfigureTelemetry(Wire::take(r, "ConfigureTelemetry", v)?)
            }
            PayloadKind::RequestTelemetry => Self::RequestTelemetry,
            PayloadKind::ConfigureAdaptive => {
                Self::ConfigureAdaptive(Wire::take(r, "ConfigureAdaptive", v)?)
            }
            PayloadKind::RequestAdaptiveStatus => Self::RequestAdaptiveStatus,
            PayloadKind::AdaptiveStatus => {
                Self::AdaptiveStatus(Wire::take(r, "AdaptiveStatus", v)?)
            }
            PayloadKind::StartCalibration => {
                Self::StartCalibration(Wire::take(r, "StartCalibration", v)?)
            }
            PayloadKind::StopCalibration => Self::StopCalibration,
            PayloadKind::CalibrationStatus => {
                Self::CalibrationStatus(Wire::take(r, "CalibrationStatus", v)?)
            }
            PayloadKind::CalibrationResult => {
                Self::CalibrationResult(Wire::take(r, "CalibrationResult", v)?)
            }
            PayloadKind::PowerMetrics => Self::PowerMetrics(Wire::take(r, "PowerMetrics", v)?),
            PayloadKind::EmergencyStop => Self::EmergencyStop(Wire::take(r, "EmergencyStop", v)?),
            PayloadKind::ConfigurePower => Self::ConfigurePower(Wire::take(r, "PowerConfig", v)?),
            PayloadKind::RequestPowerConfig => Self::RequestPowerConfig,
            PayloadKind::PowerConfigResponse => {
                Self::PowerConfigResponse(Wire::take(r, "PowerConfig", v)?)
            }
            PayloadKind::RequestFaultHistory => Self::RequestFaultHistory,
            PayloadKind::FaultHistory => Self::FaultHistory(Wire::take(r, "FaultHistory", v)?),
            PayloadKind::Ack => Self::Ack(Wire::take(r, "Ack", v)?),
            PayloadKind::Nack => Self::Nack {
                id: Wire::take(r, "Nack.id", v)?,
                error: Wire::take(r, "Nack.error", v)?,
            },
            PayloadKind::ArmReady => Self::ArmReady,
        })
    }
}

/// An iRPC message: `Message { header, payload }` in postcard 1.x, with no
/// COBS, CRC, length prefix or version byte.
///
/// ```
/// use motorwire_irpc::*;
///
/// let msg = Message {
///     header: Header { source_id: 0x0000, target_id: 0x0010, msg_id: 42 },
///     payload: Payload::SetTargetV2(SetTargetPayloadV2 {
///         target_angle: 90.0, max_velocity: 100.0, target_velocity: 0.0,
///         max_acceleration: 500.0, max_deceleration: 500.0, max_jerk: 2000.0,
///         profile: MotionProfile::SCurve, max_current: 0.0, max_temperature: 0.0,
///     }),
/// };
/// let mut buf = [0u8; 64];
/// let n = msg.encode(WireVersion::V2_0, &mut buf)?;
/// assert_eq!(&buf[..n], &[
///     0x00, 0x10, 0x2a, 0x05, 0x00, 0x00, 0xb4, 0x42, 0x00, 0x00, 0xc8, 0x42,
///     0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xfa, 0x43, 0x00, 0x00, 0xfa, 0x43,
///     0x00, 0x00, 0xfa, 0x44, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
/// ]);
/// assert_eq!(Message::decode(WireVersion::V2_0, &buf[..n])?, msg);
/// # Ok::<(), motorwire_irpc::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Message {
    /// Addressing and id.
    pub header: Header,
    /// What the message says.
    pub payload: Payload,
}

impl Message {
    fn put<O: Out>(&self, o: &mut O, v: WireVersion) -> Result<(), Stop> {
        self.header.put(o, "header", v)?;
        self.payload.put(o, v)
    }

    /// The number of bytes [`Message::encode`] writes.
    ///
    /// ```
    /// use motorwire_irpc::{Header, Message, Payload, WireVersion};
    /// let ack = Message { header: Header { source_id: 0x10, target_id: 0, msg_id: 42 }, payload: Payload::Ack(42) };
    /// assert_eq!(ack.encoded_len(WireVersion::V2_0)?, 5);
    /// # Ok::<(), motorwire_irpc::Error>(())
    /// ```
    ///
    /// # Errors
    /// As [`Message::encode`], except for buffer size.
    pub fn encoded_len(&self, v: WireVersion) -> Result<usize, Error> {
        let mut c = Counter::default();
        match self.put(&mut c, v) {
            Ok(()) => Ok(c.len),
            Err(Stop { .. }) => Err(c.into_error()),
        }
    }

    /// Encodes into `buf`, returning the number of bytes written. Messages
    /// of any length are encoded here; see [`Message::encode_frame`] for one
    /// CAN-FD frame.
    ///
    /// # Errors
    /// [`Error::PayloadNotInVersion`], [`Error::ValueNotInVersion`],
    /// [`Error::NonFinite`] (naming the field), [`Error::BufferTooSmall`].
    #[inline]
    pub fn encode(&self, v: WireVersion, buf: &mut [u8]) -> Result<usize, Error> {
        let available = buf.len();
        let mut w = SliceWriter::new(buf);
        match self.put(&mut w, v) {
            // A non-finite float: the strict pass names it (and never succeeds).
            Ok(()) if w.non_finite => Err(self.encoded_len(v).err().unwrap_or(Error::NonFinite {
                field: "message",
                offset: 0,
            })),
            Ok(()) => Ok(w.position()),
            Err(Stop { .. }) => match w.into_error() {
                Error::BufferTooSmall { .. } => Err(Error::BufferTooSmall {
                    needed: self.encoded_len(v)?,
                    available,
                }),
                e => Err(e),
            },
        }
    }

    /// Encodes into one CAN-FD frame: zero-pads to the next CAN-FD length and
    /// returns that length.
    ///
    /// ```
    /// use motorwire_irpc::{Header, Message, Payload, WireVersion};
    /// let m = Message { header: Header { source_id: 0, target_id: 0x10, msg_id: 1 }, payload: Payload::Configure };
    /// let mut frame = [0xAAu8; 64];
    /// assert_eq!(m.encode_frame(WireVersion::V2_0, &mut frame)?, 4);
    /// assert_eq!(&frame[..4], &[0x00, 0x10, 0x01, 0x01]);
    /// # Ok::<(), motorwire_irpc::Error>(())
    /// ```
    ///
    /// # Errors
    /// As [`Message::encode`], and [`Error::FrameTooLarge`] for a message
    /// over 64 bytes (it needs a segmented transport).
    pub fn encode_frame(
        &self,
        v: WireVersion,
        frame: &mut [u8; MAX_FRAME_LEN],
    ) -> Result<usize, Error> {
        let len = match self.encode(v, frame) {
            Ok(len) => len,
            Err(Error::BufferTooSmall { needed, .. }) => {
                return Err(Error::FrameTooLarge { len: needed });
            }
            Err(e) => return Err(e),
        };
        let padded = can_fd_len(len).ok_or(Error::FrameTooLarge { len })?;
        if let Some(pad) = frame.get_mut(len..padded) {
            pad.fill(0);
        }
        Ok(padded)
    }

    /// Decodes exactly one message: trailing bytes are an error.
    ///
    /// ```
    /// use motorwire_irpc::{Error, Message, WireVersion};
    /// assert_eq!(
    ///     Message::decode(WireVersion::V2_0, &[0x00, 0x10, 0x01, 0x01, 0x00]),
    ///     Err(Error::TrailingBytes { offset: 4, count: 1 })
    /// );
    /// assert_eq!(
    ///     Message::decode(WireVersion::V2_0, &[0x00, 0x10, 0x01, 0x0b]),
    ///     Err(Error::UnknownTag { tag: 11, version: WireVersion::V2_0, offset: 3 })
    /// );
    /// ```
    ///
    /// # Errors
    /// The first problem, naming the field and byte offset.
    #[inline]
    pub fn decode(v: WireVersion, bytes: &[u8]) -> Result<Self, Error> {
        let (msg, used) = Self::decode_prefix(v, bytes)?;
        if used == bytes.len() {
            Ok(msg)
        } else {
            Err(Error::TrailingBytes {
                offset: used,
                count: bytes.len() - used,
            })
        }
    }

    /// Decodes one message from the start of `bytes`, returning it and the
    /// number of bytes it took.
    ///
    /// # Errors
    /// As [`Message::decode`], but what follows the message is not examined.
    #[inline]
    pub fn decode_prefix(v: WireVersion, bytes: &[u8]) -> Result<(Self, usize), Error> {
        let mut r = Reader::new(bytes);
        let parsed = Header::take(&mut r, "header", v)
            .and_then(|header| Payload::take(&mut r, v).map(|payload| Self { header, payload }));
        match parsed {
            Ok(msg) => Ok((msg, r.position())),
            Err(Stop { .. }) => Err(r.into_error()),
        }
    }

    /// Decodes a CAN-FD frame: a valid CAN-FD length, one message, then
    /// nothing but zero padding.
    ///
    /// ```
    /// use motorwire_irpc::{Error, Message, Payload, WireVersion};
    /// let frame = [0x00, 0x10, 0x01, 0x01, 0, 0, 0, 0, 0, 0, 0, 0];
    /// assert_eq!(Message::decode_frame(WireVersion::V2_0, &frame)?.payload, Payload::Configure);
    /// assert_eq!(
    ///     Message::decode_frame(WireVersion::V2_0, &[0x00, 0x10, 0x01, 0x01, 0, 0, 0, 0, 0, 7, 0, 0]),
    ///     Err(Error::NonZeroPadding { offset: 9 })
    /// );
    /// assert_eq!(Message::decode_frame(WireVersion::V2_0, &[0; 9]), Err(Error::InvalidFrameLength { len: 9 }));
    /// # Ok::<(), motorwire_irpc::Error>(())
    /// ```
    ///
    /// # Errors
    /// [`Error::InvalidFrameLength`], [`Error::NonZeroPadding`], or as
    /// [`Message::decode`].
    pub fn decode_frame(v: WireVersion, frame: &[u8]) -> Result<Self, Error> {
        if !CAN_FD_LENGTHS.contains(&frame.len()) {
            return Err(Error::InvalidFrameLength { len: frame.len() });
        }
        let (msg, used) = Self::decode_prefix(v, frame)?;
        if let Some(i) = frame
            .get(used..)
            .and_then(|rest| rest.iter().position(|b| *b != 0))
        {
            return Err(Error::NonZeroPadding { offset: used + i });
        }
        Ok(msg)
    }
}
