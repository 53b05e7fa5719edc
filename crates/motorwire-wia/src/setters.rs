//! The chainable `with_*` setters of the messages' optional members.

/// `with_*` setters, each giving one optional member a value:
/// `with_setters!(Type { with_member: member: T, ... })` gives
/// `Type::with_member(self, member: T) -> Self`, setting `member` to
/// `Some(member)`. Nothing is checked: validation is the validator's.
macro_rules! with_setters {
    ($ty:ident { $( $method:ident: $field:ident: $arg:ty ),* $(,)? }) => {
        impl $ty {
            $(
                #[doc = concat!(
                    "This value with [`", stringify!($field), "`](Self::", stringify!($field),
                    ") set (unchecked: see [`Validator::check`](crate::Validator::check))."
                )]
                #[must_use]
                pub fn $method(mut self, $field: $arg) -> Self {
                    self.$field = Some($field);
                    self
                }
            )*
        }
    };
}

pub(crate) use with_setters;
