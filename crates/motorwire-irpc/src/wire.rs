//! postcard 1.x's wire format, by hand: varints (LEB128), zigzag for signed,
//! little-endian floats, raw bytes, 0/1 bools, structs as their fields in
//! order, enums as a varint index then the variant's fields.

use crate::{Error, WireVersion};

/// Where encoded bytes go: a caller's buffer, or a counter for `encoded_len`.
/// As with decoding, the hot path returns the zero-sized [`Stop`] and the
/// detailed [`Error`] waits in the sink.
pub(crate) trait Out {
    fn byte(&mut self, b: u8) -> Result<(), Stop>;
    fn bytes(&mut self, b: &[u8]) -> Result<(), Stop>;
    /// Writes a float that must be finite.
    fn float(&mut self, v: f32, field: &'static str) -> Result<(), Stop>;
    /// Records why encoding stopped.
    fn fail(&mut self, error: Error) -> Stop;
}

/// Writes into a caller's buffer. Floats are not checked one by one (a
/// branch each): a non-finite one only sets `non_finite`, and the caller then
/// finds the exact field with a strict [`Counter`] pass. The bytes written
/// in that case are never returned as a message.
pub(crate) struct SliceWriter<'a> {
    buf: &'a mut [u8],
    pos: usize,
    error: Option<Error>,
    pub(crate) non_finite: bool,
}

impl<'a> SliceWriter<'a> {
    pub(crate) fn new(buf: &'a mut [u8]) -> Self {
        Self {
            buf,
            pos: 0,
            error: None,
            non_finite: false,
        }
    }

    pub(crate) fn position(&self) -> usize {
        self.pos
    }

    /// The error a [`Stop`] stands for.
    pub(crate) fn into_error(self) -> Error {
        stashed(self.error, self.pos)
    }

    #[cold]
    fn full(&mut self) -> Stop {
        // The length the message needs is worked out by the caller.
        let available = self.buf.len();
        self.fail(Error::BufferTooSmall {
            needed: 0,
            available,
        })
    }
}

/// `fail` is the only constructor of [`Stop`], so an error is always stashed
/// by the time a Stop reaches the caller.
fn stashed(error: Option<Error>, pos: usize) -> Error {
    error.unwrap_or(Error::Truncated {
        field: "message",
        offset: pos,
    })
}

impl Out for SliceWriter<'_> {
    #[inline]
    fn byte(&mut self, b: u8) -> Result<(), Stop> {
        match self.buf.get_mut(self.pos) {
            Some(slot) => {
                *slot = b;
                self.pos += 1;
                Ok(())
            }
            None => Err(self.full()),
        }
    }

    #[inline]
    fn bytes(&mut self, b: &[u8]) -> Result<(), Stop> {
        let end = self.pos + b.len();
        match self.buf.get_mut(self.pos..end) {
            Some(dst) => {
                dst.copy_from_slice(b);
                self.pos = end;
                Ok(())
            }
            None => Err(self.full()),
        }
    }

    #[inline]
    fn float(&mut self, v: f32, _: &'static str) -> Result<(), Stop> {
        self.non_finite |= !v.is_finite();
        self.bytes(&v.to_le_bytes())
    }

    #[cold]
    #[inline(never)]
    fn fail(&mut self, error: Error) -> Stop {
        self.error = Some(error);
        Stop(())
    }
}

/// Counts the bytes a message needs, checking every float strictly.
#[derive(Default)]
pub(crate) struct Counter {
    pub(crate) len: usize,
    error: Option<Error>,
}

impl Counter {
    /// The error a [`Stop`] stands for.
    pub(crate) fn into_error(self) -> Error {
        stashed(self.error, self.len)
    }
}

impl Out for Counter {
    #[inline]
    fn byte(&mut self, _: u8) -> Result<(), Stop> {
        self.len += 1;
        Ok(())
    }

    #[inline]
    fn bytes(&mut self, b: &[u8]) -> Result<(), Stop> {
        self.len += b.len();
        Ok(())
    }

    #[inline]
    fn float(&mut self, v: f32, field: &'static str) -> Result<(), Stop> {
        if v.is_finite() {
            self.len += 4;
            Ok(())
        } else {
            let offset = self.len;
            Err(self.fail(Error::NonFinite { field, offset }))
        }
    }

    #[cold]
    fn fail(&mut self, error: Error) -> Stop {
        self.error = Some(error);
        Stop(())
    }
}

/// Decoding or encoding stopped; the reason is in the reader's or writer's stash. Zero-sized,
/// so a `Result<f32, Stop>` travels in registers on the hot path while the
/// detailed [`Error`] (field name, offset) is built only on failure.
pub(crate) struct Stop(());

pub(crate) struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
    error: Option<Error>,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(buf: &'a [u8]) -> Self {
        Self {
            buf,
            pos: 0,
            error: None,
        }
    }

    pub(crate) fn position(&self) -> usize {
        self.pos
    }

    /// Records why decoding stopped. The only way to make a [`Stop`].
    #[cold]
    #[inline(never)]
    pub(crate) fn fail(&mut self, error: Error) -> Stop {
        self.error = Some(error);
        Stop(())
    }

    /// The error a [`Stop`] stands for.
    pub(crate) fn into_error(self) -> Error {
        stashed(self.error, self.pos)
    }

    #[cold]
    fn truncated(&mut self, field: &'static str) -> Stop {
        let offset = self.buf.len();
        self.fail(Error::Truncated { field, offset })
    }

    #[inline]
    fn byte(&mut self, field: &'static str) -> Result<u8, Stop> {
        match self.buf.get(self.pos) {
            Some(b) => {
                self.pos += 1;
                Ok(*b)
            }
            None => Err(self.truncated(field)),
        }
    }

    #[inline]
    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], Stop> {
        let end = self.pos + N;
        match self
            .buf
            .get(self.pos..end)
            .and_then(|s| <[u8; N]>::try_from(s).ok())
        {
            Some(bytes) => {
                self.pos = end;
                Ok(bytes)
            }
            None => Err(self.truncated(field)),
        }
    }

    /// A LEB128 varint of at most `max_bytes` bytes holding at most `max`.
    #[inline]
    pub(crate) fn varint(
        &mut self,
        field: &'static str,
        max_bytes: u32,
        max: u64,
    ) -> Result<u64, Stop> {
        // Fast path: one byte, the common case for tags, node ids and enums.
        if let Some(&b) = self.buf.get(self.pos)
            && b < 0x80
        {
            let offset = self.pos;
            self.pos += 1;
            return if u64::from(b) <= max {
                Ok(u64::from(b))
            } else {
                Err(self.fail(Error::VarintOverflow { field, offset }))
            };
        }
        self.varint_slow(field, max_bytes, max)
    }

    fn varint_slow(&mut self, field: &'static str, max_bytes: u32, max: u64) -> Result<u64, Stop> {
        let offset = self.pos;
        let mut value: u64 = 0;
        for i in 0..max_bytes {
            let b = self.byte(field)?;
            let group = u64::from(b & 0x7F);
            let shifted = group << (7 * i);
            // Bits shifted out of the u64 (the 10th group of a u64 may only
            // be 0 or 1) mean the varint overflows.
            if shifted >> (7 * i) != group {
                return Err(self.fail(Error::VarintOverflow { field, offset }));
            }
            value |= shifted;
            if b & 0x80 == 0 {
                if i > 0 && b == 0 {
                    return Err(self.fail(Error::NonCanonicalVarint { field, offset }));
                }
                if value > max {
                    return Err(self.fail(Error::VarintOverflow { field, offset }));
                }
                return Ok(value);
            }
        }
        Err(self.fail(Error::VarintOverflow { field, offset }))
    }
}

#[inline]
pub(crate) fn put_varint<O: Out>(o: &mut O, mut v: u64) -> Result<(), Stop> {
    while v >= 0x80 {
        // The mask keeps 7 bits, which always fit a u8.
        #[allow(clippy::cast_possible_truncation)]
        o.byte((v as u8 & 0x7F) | 0x80)?;
        v >>= 7;
    }
    #[allow(clippy::cast_possible_truncation)]
    o.byte(v as u8)
}

/// A value with a postcard encoding.
pub(crate) trait Wire: Sized {
    fn put<O: Out>(&self, o: &mut O, field: &'static str, v: WireVersion) -> Result<(), Stop>;
    fn take(r: &mut Reader<'_>, field: &'static str, v: WireVersion) -> Result<Self, Stop>;
}

impl Wire for u8 {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Stop> {
        o.byte(*self)
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Stop> {
        r.byte(field)
    }
}

impl Wire for i8 {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Stop> {
        let [b] = self.to_le_bytes();
        o.byte(b)
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Stop> {
        r.byte(field).map(|b| i8::from_le_bytes([b]))
    }
}

macro_rules! varint_impl {
    ($ty:ty, $bytes:expr) => {
        impl Wire for $ty {
            #[inline]
            fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Stop> {
                put_varint(o, u64::from(*self))
            }
            #[inline]
            fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Stop> {
                let offset = r.position();
                let v = r.varint(field, $bytes, u64::from(<$ty>::MAX))?;
                // varint() bounded the value by MAX, so this conversion holds.
                match <$ty>::try_from(v) {
                    Ok(v) => Ok(v),
                    Err(_) => Err(r.fail(Error::VarintOverflow { field, offset })),
                }
            }
        }
    };
}

varint_impl!(u16, 3);
varint_impl!(u32, 5);
varint_impl!(u64, 10);

impl Wire for i32 {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Stop> {
        // Zigzag: 0, -1, 1, -2, ... -> 0, 1, 2, 3, ...
        #[allow(clippy::cast_sign_loss)]
        let z = ((*self << 1) ^ (*self >> 31)) as u32;
        put_varint(o, u64::from(z))
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Stop> {
        let offset = r.position();
        let z = r.varint(field, 5, u64::from(u32::MAX))?;
        let z = match u32::try_from(z) {
            Ok(z) => z,
            Err(_) => return Err(r.fail(Error::VarintOverflow { field, offset })),
        };
        #[allow(clippy::cast_possible_wrap)]
        Ok(((z >> 1) as i32) ^ -((z & 1) as i32))
    }
}

impl Wire for f32 {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, field: &'static str, _: WireVersion) -> Result<(), Stop> {
        o.float(*self, field)
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Stop> {
        let offset = r.position();
        let v = f32::from_le_bytes(r.array(field)?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(r.fail(Error::NonFinite { field, offset }))
        }
    }
}

impl Wire for bool {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Stop> {
        o.byte(u8::from(*self))
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Stop> {
        let offset = r.position();
        match r.byte(field)? {
            0 => Ok(false),
            1 => Ok(true),
            byte => Err(r.fail(Error::InvalidBool {
                field,
                byte,
                offset,
            })),
        }
    }
}

impl<T: Wire + Copy + Default, const N: usize> Wire for [T; N] {
    fn put<O: Out>(&self, o: &mut O, field: &'static str, v: WireVersion) -> Result<(), Stop> {
        for item in self {
            item.put(o, field, v)?;
        }
        Ok(())
    }
    fn take(r: &mut Reader<'_>, field: &'static str, v: WireVersion) -> Result<Self, Stop> {
        let mut out = [T::default(); N];
        for slot in &mut out {
            *slot = T::take(r, field, v)?;
        }
        Ok(out)
    }
}

/// Declares a struct whose fields are encoded in declaration order.
macro_rules! wire_struct {
    (
        $(#[$meta:meta])*
        pub struct $name:ident as $prefix:literal {
            $( $(#[$fmeta:meta])* $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
        #[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
        pub struct $name {
            $( $(#[$fmeta])* pub $field: $ty, )*
        }

        impl $crate::wire::Wire for $name {
            #[inline]
            fn put<O: $crate::wire::Out>(
                &self,
                o: &mut O,
                _: &'static str,
                v: $crate::WireVersion,
            ) -> Result<(), $crate::wire::Stop> {
                $( $crate::wire::Wire::put(&self.$field, o, concat!($prefix, ".", stringify!($field)), v)?; )*
                Ok(())
            }

            #[inline]
            fn take(
                r: &mut $crate::wire::Reader<'_>,
                _: &'static str,
                v: $crate::WireVersion,
            ) -> Result<Self, $crate::wire::Stop> {
                Ok(Self {
                    $( $field: $crate::wire::Wire::take(r, concat!($prefix, ".", stringify!($field)), v)?, )*
                })
            }
        }
    };
}
pub(crate) use wire_struct;

/// Declares a unit-only enum encoded as its declaration index.
macro_rules! wire_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $index:literal ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
        pub enum $name {
            $( $(#[$vmeta])* $variant, )*
        }

        impl $name {
            /// Every variant, in wire order.
            pub const ALL: &'static [$name] = &[$($name::$variant,)*];

            /// The variant's index on the wire.
            pub const fn index(self) -> u32 {
                match self { $( $name::$variant => $index, )* }
            }
        }

        impl $crate::wire::Wire for $name {
            #[inline]
            fn put<O: $crate::wire::Out>(
                &self,
                o: &mut O,
                _: &'static str,
                _: $crate::WireVersion,
            ) -> Result<(), $crate::wire::Stop> {
                $crate::wire::put_varint(o, u64::from(self.index()))
            }

            #[inline]
            fn take(
                r: &mut $crate::wire::Reader<'_>,
                field: &'static str,
                _: $crate::WireVersion,
            ) -> Result<Self, $crate::wire::Stop> {
                let offset = r.position();
                let index = r.varint(field, 5, u64::from(u32::MAX))?;
                match index {
                    $( $index => Ok($name::$variant), )*
                    _ => Err(r.fail($crate::Error::InvalidEnum {
                        field,
                        index: u32::try_from(index).unwrap_or(u32::MAX),
                        offset,
                    })),
                }
            }
        }
    };
}
pub(crate) use wire_enum;
