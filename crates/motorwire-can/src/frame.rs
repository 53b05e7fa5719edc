//! CAN identifiers and frames, classic and FD.

use core::fmt;

use crate::Error;

/// The largest classic CAN payload.
pub const CLASSIC_MAX_LEN: usize = 8;
/// The largest CAN-FD payload.
pub const FD_MAX_LEN: usize = 64;
/// The payload lengths a CAN-FD frame can have.
pub const FD_LENGTHS: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

/// The smallest CAN-FD frame length that holds `len` bytes, or `None` above 64.
///
/// ```
/// use motorwire_can::fd_len;
/// assert_eq!(fd_len(9), Some(12));
/// assert_eq!(fd_len(64), Some(64));
/// assert_eq!(fd_len(65), None);
/// ```
pub fn fd_len(len: usize) -> Option<usize> {
    FD_LENGTHS.into_iter().find(|l| *l >= len)
}

/// A CAN identifier: standard (11 bits) or extended (29 bits).
///
/// ```
/// use motorwire_can::CanId;
/// assert_eq!(CanId::standard(0x10)?.raw(), 0x10);
/// assert!(CanId::standard(0x800).is_err());
/// assert_eq!(CanId::extended(0x1234_5678)?.to_string(), "12345678");
/// assert_eq!(CanId::standard(0x10)?.to_string(), "010");
/// # Ok::<(), motorwire_can::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CanId {
    /// An 11-bit identifier (0 to 0x7FF).
    Standard(u16),
    /// A 29-bit identifier (0 to 0x1FFF_FFFF).
    Extended(u32),
}

impl CanId {
    /// The largest standard identifier.
    pub const MAX_STANDARD: u16 = 0x7FF;
    /// The largest extended identifier.
    pub const MAX_EXTENDED: u32 = 0x1FFF_FFFF;

    /// A standard identifier.
    ///
    /// # Errors
    /// [`Error::InvalidId`] above 0x7FF.
    pub fn standard(id: u16) -> Result<Self, Error> {
        if id > Self::MAX_STANDARD {
            return Err(Error::InvalidId {
                id: u32::from(id),
                extended: false,
            });
        }
        Ok(Self::Standard(id))
    }

    /// An extended identifier.
    ///
    /// # Errors
    /// [`Error::InvalidId`] above 0x1FFF_FFFF.
    pub fn extended(id: u32) -> Result<Self, Error> {
        if id > Self::MAX_EXTENDED {
            return Err(Error::InvalidId { id, extended: true });
        }
        Ok(Self::Extended(id))
    }

    /// The identifier's value.
    pub fn raw(self) -> u32 {
        match self {
            Self::Standard(id) => u32::from(id),
            Self::Extended(id) => id,
        }
    }

    /// Whether it is a 29-bit identifier.
    pub fn is_extended(self) -> bool {
        matches!(self, Self::Extended(_))
    }
}

impl fmt::Display for CanId {
    /// As candump writes it: three hex digits for standard, eight for extended.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Standard(id) => write!(f, "{id:03X}"),
            Self::Extended(id) => write!(f, "{id:08X}"),
        }
    }
}

/// A CAN data frame: classic (up to 8 bytes) or FD (one of the FD lengths
/// up to 64, zero-padded by the constructors).
///
/// ```
/// use motorwire_can::{CanId, Frame};
/// let id = CanId::standard(0x000)?;
/// // 37 bytes of iRPC become a 48-byte FD frame, the rest zeros.
/// let f = Frame::fd(id, &[0xAB; 37])?;
/// assert_eq!(f.len(), 48);
/// assert_eq!(&f.data()[36..38], &[0xAB, 0x00]);
/// let c = Frame::classic(id, &[1, 2, 3])?;
/// assert_eq!((c.is_fd(), c.data()), (false, &[1u8, 2, 3][..]));
/// assert!(Frame::classic(id, &[0; 9]).is_err());
/// # Ok::<(), motorwire_can::Error>(())
/// ```
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Frame {
    id: CanId,
    fd: bool,
    brs: bool,
    esi: bool,
    len: u8,
    data: [u8; FD_MAX_LEN],
}

impl Frame {
    /// A classic CAN frame of `data.len()` bytes.
    ///
    /// # Errors
    /// [`Error::InvalidLength`] over 8 bytes.
    pub fn classic(id: CanId, data: &[u8]) -> Result<Self, Error> {
        if data.len() > CLASSIC_MAX_LEN {
            return Err(Error::InvalidLength {
                len: data.len(),
                fd: false,
            });
        }
        Ok(Self::filled(id, false, data, data.len()))
    }

    /// A CAN-FD frame holding `data`, zero-padded to the next FD length, with
    /// bit-rate switching on.
    ///
    /// # Errors
    /// [`Error::InvalidLength`] over 64 bytes.
    pub fn fd(id: CanId, data: &[u8]) -> Result<Self, Error> {
        let len = fd_len(data.len()).ok_or(Error::InvalidLength {
            len: data.len(),
            fd: true,
        })?;
        let mut f = Self::filled(id, true, data, len);
        f.brs = true;
        Ok(f)
    }

    /// A CAN-FD frame of exactly `data.len()` bytes, which must be an FD
    /// length (for frames read from a bus or a log, which are never padded
    /// again).
    ///
    /// # Errors
    /// [`Error::InvalidLength`] for a length that is not an FD length.
    pub fn fd_exact(id: CanId, data: &[u8], brs: bool, esi: bool) -> Result<Self, Error> {
        if !FD_LENGTHS.contains(&data.len()) {
            return Err(Error::InvalidLength {
                len: data.len(),
                fd: true,
            });
        }
        let mut f = Self::filled(id, true, data, data.len());
        f.brs = brs;
        f.esi = esi;
        Ok(f)
    }

    fn filled(id: CanId, fd: bool, data: &[u8], len: usize) -> Self {
        let mut buf = [0u8; FD_MAX_LEN];
        if let Some(dst) = buf.get_mut(..data.len()) {
            dst.copy_from_slice(data);
        }
        Self {
            id,
            fd,
            brs: false,
            esi: false,
            len: u8::try_from(len).unwrap_or(u8::MAX),
            data: buf,
        }
    }

    /// The identifier.
    pub fn id(&self) -> CanId {
        self.id
    }

    /// Whether it is a CAN-FD frame.
    pub fn is_fd(&self) -> bool {
        self.fd
    }

    /// CAN-FD bit-rate switch flag.
    pub fn brs(&self) -> bool {
        self.brs
    }

    /// CAN-FD error-state indicator flag.
    pub fn esi(&self) -> bool {
        self.esi
    }

    /// The payload length, padding included.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// Whether the payload is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The payload, padding included.
    pub fn data(&self) -> &[u8] {
        self.data.get(..self.len()).unwrap_or(&[])
    }

    /// The payload, mutable (fault injection, tests).
    pub fn data_mut(&mut self) -> &mut [u8] {
        let len = self.len();
        self.data.get_mut(..len).unwrap_or(&mut [])
    }
}

impl fmt::Debug for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Frame({self})")
    }
}

impl fmt::Display for Frame {
    /// The candump `-L` form: `010#0102` or `010##1` followed by the FD flags
    /// digit and the data.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}#", self.id)?;
        if self.fd {
            let flags = u8::from(self.brs) | (u8::from(self.esi) << 1);
            write!(f, "#{flags:X}")?;
        }
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}
