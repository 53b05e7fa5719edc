//! postcard 1.x's wire format, by hand: varints (LEB128), zigzag for signed,
//! little-endian floats, raw bytes, 0/1 bools, structs as their fields in
//! order, enums as a varint index then the variant's fields.

use crate::{Error, WireVersion};

/// Where encoded bytes go: a caller's buffer, or a counter for `encoded_len`.
pub(crate) trait Out {
    fn byte(&mut self, b: u8) -> Result<(), Error>;
    fn bytes(&mut self, b: &[u8]) -> Result<(), Error>;
}

pub(crate) struct SliceWriter<'a> {
    buf: &'a mut [u8],
    pos: usize,
}

impl<'a> SliceWriter<'a> {
    pub(crate) fn new(buf: &'a mut [u8]) -> Self {
        Self { buf, pos: 0 }
    }

    pub(crate) fn position(&self) -> usize {
        self.pos
    }
}

/// A marker error: the real `BufferTooSmall` is built by the caller, who can
/// compute the length the message needs.
const FULL: Error = Error::BufferTooSmall {
    needed: 0,
    available: 0,
};

impl Out for SliceWriter<'_> {
    #[inline]
    fn byte(&mut self, b: u8) -> Result<(), Error> {
        let slot = self.buf.get_mut(self.pos).ok_or(FULL)?;
        *slot = b;
        self.pos += 1;
        Ok(())
    }

    #[inline]
    fn bytes(&mut self, b: &[u8]) -> Result<(), Error> {
        let end = self.pos + b.len();
        self.buf
            .get_mut(self.pos..end)
            .ok_or(FULL)?
            .copy_from_slice(b);
        self.pos = end;
        Ok(())
    }
}

#[derive(Default)]
pub(crate) struct Counter(pub(crate) usize);

impl Out for Counter {
    #[inline]
    fn byte(&mut self, _: u8) -> Result<(), Error> {
        self.0 += 1;
        Ok(())
    }

    #[inline]
    fn bytes(&mut self, b: &[u8]) -> Result<(), Error> {
        self.0 += b.len();
        Ok(())
    }
}

pub(crate) struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(buf: &'a [u8]) -> Self {
        Self { buf, pos: 0 }
    }

    pub(crate) fn position(&self) -> usize {
        self.pos
    }

    #[inline]
    fn byte(&mut self, field: &'static str) -> Result<u8, Error> {
        let b = *self.buf.get(self.pos).ok_or(Error::Truncated {
            field,
            offset: self.buf.len(),
        })?;
        self.pos += 1;
        Ok(b)
    }

    #[inline]
    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], Error> {
        let end = self.pos + N;
        let bytes: [u8; N] = self
            .buf
            .get(self.pos..end)
            .and_then(|s| s.try_into().ok())
            .ok_or(Error::Truncated {
                field,
                offset: self.buf.len(),
            })?;
        self.pos = end;
        Ok(bytes)
    }

    /// A LEB128 varint of at most `max_bytes` bytes holding at most `max`.
    #[inline]
    pub(crate) fn varint(
        &mut self,
        field: &'static str,
        max_bytes: u32,
        max: u64,
    ) -> Result<u64, Error> {
        let offset = self.pos;
        let mut value: u64 = 0;
        for i in 0..max_bytes {
            let b = self.byte(field)?;
            let group = u64::from(b & 0x7F);
            let shifted = group << (7 * i);
            // Bits shifted out of the u64 (the 10th group of a u64 may only
            // be 0 or 1) mean the varint overflows.
            if shifted >> (7 * i) != group {
                return Err(Error::VarintOverflow { field, offset });
            }
            value |= shifted;
            if b & 0x80 == 0 {
                if i > 0 && b == 0 {
                    return Err(Error::NonCanonicalVarint { field, offset });
                }
                if value > max {
                    return Err(Error::VarintOverflow { field, offset });
                }
                return Ok(value);
            }
        }
        Err(Error::VarintOverflow { field, offset })
    }
}

#[inline]
pub(crate) fn put_varint<O: Out>(o: &mut O, mut v: u64) -> Result<(), Error> {
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
    fn put<O: Out>(&self, o: &mut O, field: &'static str, v: WireVersion) -> Result<(), Error>;
    fn take(r: &mut Reader<'_>, field: &'static str, v: WireVersion) -> Result<Self, Error>;
}

impl Wire for u8 {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Error> {
        o.byte(*self)
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Error> {
        r.byte(field)
    }
}

impl Wire for i8 {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Error> {
        let [b] = self.to_le_bytes();
        o.byte(b)
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Error> {
        r.byte(field).map(|b| i8::from_le_bytes([b]))
    }
}

macro_rules! varint_impl {
    ($ty:ty, $bytes:expr) => {
        impl Wire for $ty {
            #[inline]
            fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Error> {
                put_varint(o, u64::from(*self))
            }
            #[inline]
            fn take(
                r: &mut Reader<'_>,
                field: &'static str,
                _: WireVersion,
            ) -> Result<Self, Error> {
                let v = r.varint(field, $bytes, u64::from(<$ty>::MAX))?;
                // varint() bounded the value by MAX.
                <$ty>::try_from(v).map_err(|_| Error::VarintOverflow {
                    field,
                    offset: r.position(),
                })
            }
        }
    };
}

varint_impl!(u16, 3);
varint_impl!(u32, 5);
varint_impl!(u64, 10);

impl Wire for i32 {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Error> {
        // Zigzag: 0, -1, 1, -2, ... -> 0, 1, 2, 3, ...
        #[allow(clippy::cast_sign_loss)]
        let z = ((*self << 1) ^ (*self >> 31)) as u32;
        put_varint(o, u64::from(z))
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Error> {
        let z = r.varint(field, 5, u64::from(u32::MAX))?;
        let z = u32::try_from(z).map_err(|_| Error::VarintOverflow {
            field,
            offset: r.position(),
        })?;
        #[allow(clippy::cast_possible_wrap)]
        Ok(((z >> 1) as i32) ^ -((z & 1) as i32))
    }
}

impl Wire for f32 {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, field: &'static str, _: WireVersion) -> Result<(), Error> {
        if !self.is_finite() {
            return Err(Error::NonFinite { field, offset: 0 });
        }
        o.bytes(&self.to_le_bytes())
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Error> {
        let offset = r.position();
        let v = f32::from_le_bytes(r.array(field)?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(Error::NonFinite { field, offset })
        }
    }
}

impl Wire for bool {
    #[inline]
    fn put<O: Out>(&self, o: &mut O, _: &'static str, _: WireVersion) -> Result<(), Error> {
        o.byte(u8::from(*self))
    }
    #[inline]
    fn take(r: &mut Reader<'_>, field: &'static str, _: WireVersion) -> Result<Self, Error> {
        let offset = r.position();
        match r.byte(field)? {
            0 => Ok(false),
            1 => Ok(true),
            byte => Err(Error::InvalidBool {
                field,
                byte,
                offset,
            }),
        }
    }
}

impl<T: Wire + Copy + Default, const N: usize> Wire for [T; N] {
    fn put<O: Out>(&self, o: &mut O, field: &'static str, v: WireVersion) -> Result<(), Error> {
        for item in self {
            item.put(o, field, v)?;
        }
        Ok(())
    }
    fn take(r: &mut Reader<'_>, field: &'static str, v: WireVersion) -> Result<Self, Error> {
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
            ) -> Result<(), $crate::Error> {
                $( $crate::wire::Wire::put(&self.$field, o, concat!($prefix, ".", stringify!($field)), v)?; )*
                Ok(())
            }

            #[inline]
            fn take(
                r: &mut $crate::wire::Reader<'_>,
                _: &'static str,
                v: $crate::WireVersion,
            ) -> Result<Self, $crate::Error> {
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
            ) -> Result<(), $crate::Error> {
                $crate::wire::put_varint(o, u64::from(self.index()))
            }

            #[inline]
            fn take(
                r: &mut $crate::wire::Reader<'_>,
                field: &'static str,
                _: $crate::WireVersion,
            ) -> Result<Self, $crate::Error> {
                let offset = r.position();
                let index = r.varint(field, 5, u64::from(u32::MAX))?;
                match index {
                    $( $index => Ok($name::$variant), )*
                    _ => Err($crate::Error::InvalidEnum {
                        field,
                        index: u32::try_from(index).unwrap_or(u32::MAX),
                        offset,
                    }),
                }
            }
        }
    };
}
pub(crate) use wire_enum;
