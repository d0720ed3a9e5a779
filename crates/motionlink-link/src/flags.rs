//! The one flag-set mechanism of every family: a table of named bits becomes a flag enum and a word type
//! ([`flag_set!`](crate::flag_set)), and generic code (the command line's tables and JSON, the Python
//! bindings, the web console) reads any of them through [`FlagWord`] and [`Flag`].
//!
//! ```
//! motionlink_link::flag_set! {
//!     /// Two lamps.
//!     Lamps(u8);
//!     /// One lamp.
//!     Lamp {
//!         Red = ("RED", 0x01, Error, "Something is wrong."),
//!         Green = ("GREEN", 0x02, Information, "All is well."),
//!     }
//! }
//! use motionlink_link::flags::FlagWord;
//! let w = Lamps(0x03 | 0x80);
//! assert_eq!(w.to_string(), "RED | GREEN | 0x80");
//! assert_eq!(w.names(), vec!["RED", "GREEN"]);
//! assert_eq!(w.unknown(), 0x80);
//! ```

use std::fmt;

/// What a flag tells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FlagClass {
    /// An error: the device has stopped or refuses motion.
    Error,
    /// A warning: the device still works, but something needs attention.
    Warning,
    /// Information on the device's state.
    Information,
    /// A flag of old firmware, still decoded.
    Obsolete,
}

impl FlagClass {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            FlagClass::Error => "error",
            FlagClass::Warning => "warning",
            FlagClass::Information => "information",
            FlagClass::Obsolete => "obsolete",
        }
    }
}

impl fmt::Display for FlagClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One named flag of a table.
pub trait Flag: Copy + fmt::Debug + 'static {
    /// The manual's name.
    fn name(self) -> &'static str;
    /// The flag's bit(s), widened.
    fn mask_u64(self) -> u64;
    /// What the flag tells.
    fn class(self) -> FlagClass;
    /// The manual's explanation.
    fn meaning(self) -> &'static str;
}

/// A word of flags, read generically.
pub trait FlagWord: Copy + fmt::Display {
    /// The flags of this word.
    type Flag: Flag;
    /// The raw word, widened.
    fn raw(self) -> u64;
    /// Every flag set, in the table's order (a bit the table names twice is reported once).
    fn set_flags(self) -> Vec<Self::Flag>;
    /// Bits set that no flag names.
    fn unknown(self) -> u64;
    /// The names of the flags set.
    fn names(self) -> Vec<&'static str> {
        self.set_flags().into_iter().map(Flag::name).collect()
    }
    /// True if a set flag is of class [`FlagClass::Error`].
    fn has_error(self) -> bool {
        self.set_flags().into_iter().any(|f| f.class() == FlagClass::Error)
    }
}

/// A flag word as every result shows it (the `--json` of every command, Python's records, the console, the
/// gateway): `word` (the raw word), `flags` (the manual's names of the bits set, in the table's order) and
/// `unknown_bits` (the bits no name covers), only when nonzero. Every word of [`flag_set!`](crate::flag_set) serialises so.
#[derive(Debug, Clone, Copy)]
pub struct WordView<W>(pub W);

impl<W: FlagWord> serde::Serialize for WordView<W> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let unknown = self.0.unknown();
        let mut map = s.serialize_map(Some(if unknown != 0 { 3 } else { 2 }))?;
        map.serialize_entry("word", &self.0.raw())?;
        map.serialize_entry("flags", &self.0.names())?;
        if unknown != 0 {
            map.serialize_entry("unknown_bits", &unknown)?;
        }
        map.end()
    }
}

/// Generates a flag enum and a word type from one table: `Variant = ("NAME", mask, Class, "meaning")`,
/// where Class is a [`FlagClass`] variant; a table whose manual also says what a clear bit means adds it as
/// a fifth element, `("NAME", mask, Class, "meaning when set", "meaning when clear")`. The word type implements [`FlagWord`], `Display` (the names
/// joined by ` | `, unknown bits in hex, `-` for none) and `Debug`; the flag enum implements [`Flag`].
#[macro_export]
macro_rules! flag_set {
    (
        $(#[$smeta:meta])* $set:ident($raw:ty);
        $(#[$fmeta:meta])* $flag:ident {
            $( $var:ident = ($name:literal, $mask:expr, $class:ident, $doc:literal $(, $clear:literal)?) ),* $(,)?
        }
    ) => {
        $(#[$fmeta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $flag {
            $( #[doc = $doc] $var ),*
        }

        impl $flag {
            /// Every flag, in the manual's order.
            pub const ALL: &'static [$flag] = &[$($flag::$var),*];

            /// The manual's name.
            pub fn name(self) -> &'static str {
                match self { $($flag::$var => $name),* }
            }

            /// The flag's bit(s).
            pub const fn mask(self) -> $raw {
                match self { $($flag::$var => $mask),* }
            }

            /// What the flag tells.
            pub fn class(self) -> $crate::flags::FlagClass {
                match self { $($flag::$var => $crate::flags::FlagClass::$class),* }
            }

            /// The manual's explanation.
            pub fn meaning(self) -> &'static str {
                match self { $($flag::$var => $doc),* }
            }

            /// What the manual says the flag's bit means when it is clear, where its table says it.
            pub fn clear_meaning(self) -> ::std::option::Option<&'static str> {
                match self {
                    $($flag::$var => {
                        let clear: &[&'static str] = &[$($clear)?];
                        clear.first().copied()
                    }),*
                }
            }

            /// The name to show for the flag's bit: its name, followed in parentheses by the other names
            /// the manual gives the same bit.
            pub fn label(self) -> ::std::string::String {
                let mut label = ::std::string::String::from(self.name());
                for other in $flag::ALL.iter().filter(|g| **g != self && g.mask() == self.mask()) {
                    label.push_str(" (");
                    label.push_str(other.name());
                    label.push(')');
                }
                label
            }

            /// The flag with this name (case-insensitive), if any.
            pub fn from_name(name: &str) -> ::std::option::Option<$flag> {
                Self::ALL.iter().copied().find(|f| f.name().eq_ignore_ascii_case(name))
            }
        }

        impl $crate::flags::Flag for $flag {
            fn name(self) -> &'static str {
                $flag::name(self)
            }
            fn mask_u64(self) -> u64 {
                u64::from($flag::mask(self))
            }
            fn class(self) -> $crate::flags::FlagClass {
                $flag::class(self)
            }
            fn meaning(self) -> &'static str {
                $flag::meaning(self)
            }
        }

        $(#[$smeta])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
        pub struct $set(pub $raw);

        impl $set {
            /// No flag set.
            pub const EMPTY: $set = $set(0);

            /// The raw word.
            pub fn bits(self) -> $raw {
                self.0
            }

            /// True if `flag` is set.
            pub fn contains(self, flag: $flag) -> bool {
                self.0 & flag.mask() == flag.mask()
            }

            /// The set with `flag` added.
            #[must_use]
            pub fn with(self, flag: $flag) -> Self {
                $set(self.0 | flag.mask())
            }

            /// The set with `flag` removed.
            #[must_use]
            pub fn without(self, flag: $flag) -> Self {
                $set(self.0 & !flag.mask())
            }

            /// Adds or removes `flag`.
            pub fn set(&mut self, flag: $flag, on: bool) {
                *self = if on { self.with(flag) } else { self.without(flag) };
            }

            /// The flags set, in the manual's order. Where the manual gives two names to one bit, the first
            /// is reported, once (its `label()` names the other too).
            pub fn iter(self) -> impl Iterator<Item = $flag> {
                $flag::ALL.iter().enumerate().filter_map(move |(i, &f)| {
                    let first = !$flag::ALL[..i].iter().any(|g| g.mask() == f.mask());
                    (first && self.contains(f)).then_some(f)
                })
            }

            /// Bits set that no flag names.
            pub fn unknown_bits(self) -> $raw {
                let known = $flag::ALL.iter().fold(0, |acc, f| acc | f.mask());
                self.0 & !known
            }

            /// True if no bit is set.
            pub fn is_empty(self) -> bool {
                self.0 == 0
            }
        }

        impl $crate::flags::FlagWord for $set {
            type Flag = $flag;
            fn raw(self) -> u64 {
                u64::from(self.0)
            }
            fn set_flags(self) -> ::std::vec::Vec<$flag> {
                self.iter().collect()
            }
            fn unknown(self) -> u64 {
                u64::from(self.unknown_bits())
            }
        }

        /// As every result shows a flag word: `{"word", "flags", "unknown_bits"}` ([`$crate::flags::WordView`]).
        impl $crate::serde::Serialize for $set {
            fn serialize<S: $crate::serde::Serializer>(&self, s: S) -> ::std::result::Result<S::Ok, S::Error> {
                $crate::serde::Serialize::serialize(&$crate::flags::WordView(*self), s)
            }
        }

        impl ::std::fmt::Debug for $set {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                write!(f, "{}({:#x}: {})", stringify!($set), self.0, self)
            }
        }

        /// The names of the flags set, joined by `|` (`-` for none), unknown bits in hex.
        impl ::std::fmt::Display for $set {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                let mut first = true;
                for flag in self.iter() {
                    if !first {
                        f.write_str(" | ")?;
                    }
                    f.write_str(&flag.label())?;
                    first = false;
                }
                let unknown = self.unknown_bits();
                if unknown != 0 {
                    if !first {
                        f.write_str(" | ")?;
                    }
                    write!(f, "{:#x}", unknown)?;
                    first = false;
                }
                if first {
                    f.write_str("-")?;
                }
                Ok(())
            }
        }
    };
}

#[cfg(test)]
#[allow(dead_code)] // the generated word type has more than the test uses
mod tests {
    use super::*;

    crate::flag_set! {
        /// A test word.
        Word(u16);
        /// A test flag.
        Bit {
            A = ("A", 0x0001, Error, "a"),
            B = ("B", 0x0002, Information, "b"),
            BTwice = ("B_AGAIN", 0x0002, Obsolete, "b under another name"),
            C = ("C", 0x0004, Information, "c on", "c off"),
        }
    }

    #[test]
    fn a_bit_named_twice_is_listed_once_with_both_names() {
        let w = Word(0x0003);
        assert_eq!(w.set_flags(), vec![Bit::A, Bit::B]);
        assert_eq!(w.to_string(), "A | B (B_AGAIN)");
        assert!(w.has_error());
        assert!(!Word(0x0002).has_error());
        assert_eq!(Word(0).to_string(), "-");
        assert_eq!(Bit::from_name("b_again"), Some(Bit::BTwice));
    }

    #[test]
    fn a_table_may_say_what_a_clear_bit_means() {
        assert_eq!((Bit::C.meaning(), Bit::C.clear_meaning()), ("c on", Some("c off")));
        assert_eq!(Bit::A.clear_meaning(), None);
    }
}
