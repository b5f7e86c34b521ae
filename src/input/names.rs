//! Enums whose values are names (`assembled`, `edge-to-edge`, `dense`): each name written once,
//! in a `named!` list, which gives the enum its serde names (scenes, outputs), its
//! [`Named`] list and its [`FromStr`](std::str::FromStr). The command line, the Python
//! bindings and `rbsm tradeoff` parse such options through it, so that they accept, and refuse
//! in the same words, what scenes do.

/// An enum of names, as `named!` (crate-internal) makes it.
pub trait Named: Copy + Sized + 'static {
    /// Every value, in the order of the list.
    const ALL: &'static [Self];

    /// The name of `self`, as scenes, options and outputs write it.
    fn name(self) -> &'static str;

    /// What `self` is: its doc comment, on one line (the command line's help lists it).
    fn help(self) -> &'static str;

    /// The value named `name`.
    ///
    /// # Errors
    /// `name` is none of [`Named::ALL`]'s names; the message lists them.
    fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|v| v.name() == name)
            .ok_or_else(|| must_be(&Self::names(), name))
    }

    /// Every name, in the order of the list.
    fn names() -> Vec<&'static str> {
        Self::ALL.iter().map(|v| v.name()).collect()
    }
}

/// `a`, `a or b`, `a, b or c`: a list of names as the messages write it.
pub fn or_list(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => (*one).to_string(),
        [init @ .., last] => format!("{} or {last}", init.join(", ")),
    }
}

/// Why `got` is none of `names`: `must be a, b or c, got `x``.
pub fn must_be(names: &[&str], got: &str) -> String {
    format!("must be {}, got `{got}`", or_list(names))
}

/// An enum of names, each written once: `"name" => Variant` with its doc comment. Gives the
/// enum (serde names from the list, so `#[derive(JsonSchema)]` beside it follows them too),
/// `ALL`, `name()`, [`Named`], [`FromStr`](std::str::FromStr) and `Display`. A default value
/// is an `impl Default` of its own.
macro_rules! named {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident {
            $(
                $(#[doc = $doc:literal])*
                $label:literal => $variant:ident
            ),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(serde::Serialize, serde::Deserialize)]
        $vis enum $name {
            $(
                $(#[doc = $doc])*
                #[serde(rename = $label)]
                $variant,
            )+
        }

        impl $name {
            /// Every value, in the order of the list.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];

            /// The name used in scenes, options and outputs.
            pub fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $label,)+
                }
            }
        }

        impl $crate::input::names::Named for $name {
            const ALL: &'static [$name] = $name::ALL;

            fn name(self) -> &'static str {
                $name::name(self)
            }

            fn help(self) -> &'static str {
                match self {
                    $($name::$variant => concat!($($doc),*).trim(),)+
                }
            }
        }

        impl std::str::FromStr for $name {
            type Err = String;

            /// The value named `name`; the error says what the names are.
            fn from_str(name: &str) -> std::result::Result<Self, String> {
                <$name as $crate::input::names::Named>::from_name(name)
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}
pub(crate) use named;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_read_as_prose() {
        assert_eq!(or_list(&["a"]), "a");
        assert_eq!(or_list(&["a", "b"]), "a or b");
        assert_eq!(or_list(&["a", "b", "c"]), "a, b or c");
        assert_eq!(must_be(&["a", "b"], "x"), "must be a or b, got `x`");
    }
}
