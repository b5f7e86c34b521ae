//! Objects told apart by a `kind` key (`{"kind": "grid", ...}`): each enum of them written
//! once, in a [`kinds!`] list, which gives the enum, its `Deserialize`, its JSON Schema (one
//! object per kind) and the list of kinds an unknown one is told.
//!
//! Dispatching by hand, rather than with serde's internally tagged enums, keeps the path of an
//! error inside the variant (`bodies[0].mesh.cells`), which serde's buffering would lose, and
//! refuses the keys a kind does not have (serde's unit variants would accept and drop them, so
//! `{"kind": "rigid", "penalty": 100}` would pass silently).

use schemars::{json_schema, JsonSchema, Schema, SchemaGenerator};
use serde::Deserialize;

/// The keys of a `kind` that has none: an object with only `kind`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct NoKeys {}

/// Splits an object with a `kind` key into the kind and the other keys.
pub(crate) fn split_kind<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> std::result::Result<(String, serde_json::Value), D::Error> {
    use serde::de::Error as _;
    let mut value = serde_json::Value::deserialize(d)?;
    let map = value
        .as_object_mut()
        .ok_or_else(|| D::Error::custom("expected an object with a `kind` key"))?;
    match map.remove("kind") {
        Some(serde_json::Value::String(kind)) => Ok((kind, value)),
        Some(other) => Err(D::Error::custom(format!(
            "`kind` must be a string, got {other}"
        ))),
        None => Err(D::Error::missing_field("kind")),
    }
}

/// Deserialises the keys of one variant; an error names the key path within the variant
/// (`Scene::parse` continues the outer path with it).
pub(crate) fn variant<T: serde::de::DeserializeOwned, E: serde::de::Error>(
    rest: serde_json::Value,
) -> std::result::Result<T, E> {
    serde_path_to_error::deserialize(rest).map_err(|e| {
        let path = e.path().to_string();
        E::custom(if path == "." {
            e.into_inner().to_string()
        } else {
            format!("`{path}`: {}", e.into_inner())
        })
    })
}

/// An unknown kind, and the kinds there are.
pub(crate) fn unknown_kind<E: serde::de::Error>(kind: &str, allowed: &[&str]) -> E {
    E::custom(format!(
        "unknown kind `{kind}`, expected one of: {}",
        allowed.join(", ")
    ))
}

/// The schema of one kind of a `kind`-keyed object (read by [`split_kind`] and [`variant`]):
/// the variant's own object schema with the key `kind`, a constant, added and required.
pub(crate) fn kind_variant<T: JsonSchema>(generator: &mut SchemaGenerator, kind: &str) -> Schema {
    let mut schema = T::json_schema(generator);
    let object = schema.ensure_object();
    let properties = object
        .entry("properties")
        .or_insert_with(|| serde_json::json!({}));
    if let Some(properties) = properties.as_object_mut() {
        properties.insert(
            "kind".into(),
            serde_json::json!({"type": "string", "const": kind}),
        );
    }
    let required = object
        .entry("required")
        .or_insert_with(|| serde_json::json!([]));
    if let Some(required) = required.as_array_mut() {
        required.insert(0, "kind".into());
    }
    schema
}

/// Exactly one of `variants`, each told by its `kind`.
pub(crate) fn one_of_kinds(description: &str, variants: Vec<Schema>) -> Schema {
    json_schema!({
        "description": description,
        "type": "object",
        "required": ["kind"],
        "oneOf": variants,
    })
}

/// `` `a` ``, `` `a` or `b` ``, `` `a`, `b` or `c` ``: string literals as a list in prose, at
/// compile time (for doc comments).
macro_rules! or_list {
    ($a:literal) => { concat!("`", $a, "`") };
    ($a:literal, $b:literal) => { concat!("`", $a, "` or `", $b, "`") };
    ($a:literal, $($rest:literal),+) => {
        concat!("`", $a, "`, ", $crate::input::kinds::or_list!($($rest),+))
    };
}
pub(crate) use or_list;

/// An enum of `kind`-keyed objects, each kind written once:
///
/// ```text
/// kinds! {
///     #[derive(Debug, Clone)]
///     pub enum LoadSpec: "A load on a body" {
///         /// `traction`.
///         "traction" => Traction(TractionSpec),   // the keys of a struct
///         /// Springs that never yield.
///         "elastic" => Elastic,                   // no keys
///         /// ...
///         "hybrid" => Hybrid {                    // keys of its own
///             /// The penalty ...
///             #[schemars(transform = PENALTY)]
///             penalty: f64,
///         },
///     }
/// }
/// ```
///
/// gives the enum (its doc comment the summary and its kinds), `KINDS`, `kind()`, a
/// `Deserialize` that refuses an unknown kind with the list of kinds and the keys a kind does
/// not have, a `Serialize` that writes what it reads (a struct's keys need `Serialize`), and a
/// `JsonSchema` with one closed object per kind: a struct's own schema, or the variant's doc
/// comment and keys. A default value is an `impl Default` of its own.
macro_rules! kinds {
    // The keys of a kind that has none.
    (@read $rest:ident, $name:ident :: $variant:ident, [], []) => {
        $crate::input::kinds::variant($rest).map(|$crate::input::kinds::NoKeys {}| $name::$variant)
    };
    // The keys of a kind of its own: a struct of them, closed.
    (@read $rest:ident, $name:ident :: $variant:ident, [], [{ $($field:ident : $fty:ty),* }]) => {{
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Keys {
            $($field: $fty),*
        }
        $crate::input::kinds::variant($rest).map(|k: Keys| $name::$variant { $($field: k.$field),* })
    }};
    // The keys of a struct.
    (@read $rest:ident, $name:ident :: $variant:ident, [$inner:ty], []) => {
        $crate::input::kinds::variant($rest).map($name::$variant)
    };
    // A value's pattern, binding its keys (a struct as `$x`).
    (@pattern $name:ident :: $variant:ident, $x:ident, [], []) => { $name::$variant };
    (@pattern $name:ident :: $variant:ident, $x:ident, [], [{ $($field:ident),* }]) => {
        $name::$variant { $($field),* }
    };
    (@pattern $name:ident :: $variant:ident, $x:ident, [$inner:ty], []) => { $name::$variant($x) };
    // The keys of a value bound by its pattern, as a JSON object.
    (@keys $x:ident, [], []) => {
        Ok(serde_json::Value::Object(serde_json::Map::new()))
    };
    (@keys $x:ident, [], [{ $($field:ident),* }]) => {
        [$( (stringify!($field), serde_json::to_value($field)) ),*]
            .into_iter()
            .map(|(key, value)| value.map(|value| (key.to_string(), value)))
            .collect::<std::result::Result<serde_json::Map<_, _>, _>>()
            .map(serde_json::Value::Object)
    };
    (@keys $x:ident, [$inner:ty], []) => { serde_json::to_value($x) };
    (@schema $g:ident, $kind:literal, [$(#[$doc:meta])*], [], [$({
        $( [$(#[$fmeta:meta])*] $field:ident : $fty:ty ),*
    })?]) => {{
        #[derive(schemars::JsonSchema)]
        #[serde(deny_unknown_fields)]
        $(#[$doc])*
        #[allow(dead_code)]
        struct Keys {
            $($( $(#[$fmeta])* $field: $fty ),*)?
        }
        $crate::input::kinds::kind_variant::<Keys>($g, $kind)
    }};
    (@schema $g:ident, $kind:literal, [$(#[$doc:meta])*], [$inner:ty], []) => {
        $crate::input::kinds::kind_variant::<$inner>($g, $kind)
    };
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident: $summary:literal {
            $(
                $(#[doc = $vdoc:literal])*
                $kind:literal => $variant:ident
                $( ( $inner:ty ) )?
                $( {
                    $(
                        $(#[doc = $fdoc:literal])*
                        $(#[schemars($($fattr:tt)*)])?
                        $field:ident : $fty:ty
                    ),* $(,)?
                } )?
            ),+ $(,)?
        }
    ) => {
        #[doc = concat!(
            $summary, " (`kind`: ", $crate::input::kinds::or_list!($($kind),+), ")."
        )]
        $(#[$meta])*
        $vis enum $name {
            $(
                $(#[doc = $vdoc])*
                $variant $( ($inner) )? $( { $( $(#[doc = $fdoc])* $field: $fty ),* } )?,
            )+
        }

        impl $name {
            /// Its kinds, as scenes write them (`kind`).
            pub const KINDS: &'static [&'static str] = &[$($kind),+];

            /// Its description: the summary and the kinds.
            const DESCRIPTION: &'static str = concat!(
                $summary, " (`kind`: ", $crate::input::kinds::or_list!($($kind),+), ")."
            );

            /// The kind of this value, as scenes write it.
            pub fn kind(&self) -> &'static str {
                match self {
                    $($name::$variant { .. } => $kind,)+
                }
            }
        }

        impl<'de> serde::Deserialize<'de> for $name {
            fn deserialize<D: serde::Deserializer<'de>>(
                d: D,
            ) -> std::result::Result<Self, D::Error> {
                let (kind, rest) = $crate::input::kinds::split_kind(d)?;
                $(
                    if kind == $kind {
                        return $crate::input::kinds::kinds!(
                            @read rest, $name::$variant, [$($inner)?],
                            [$( { $($field : $fty),* } )?]
                        );
                    }
                )+
                Err($crate::input::kinds::unknown_kind(&kind, $name::KINDS))
            }
        }

        /// The keys and the `kind`, as its `Deserialize` reads them.
        impl serde::Serialize for $name {
            fn serialize<S: serde::Serializer>(
                &self,
                s: S,
            ) -> std::result::Result<S::Ok, S::Error> {
                let keys: std::result::Result<serde_json::Value, serde_json::Error> = match self {
                    $(
                        $crate::input::kinds::kinds!(
                            @pattern $name::$variant, x, [$($inner)?], [$( { $($field),* } )?]
                        ) => $crate::input::kinds::kinds!(
                            @keys x, [$($inner)?], [$( { $($field),* } )?]
                        ),
                    )+
                };
                let mut value = keys.map_err(serde::ser::Error::custom)?;
                if let Some(map) = value.as_object_mut() {
                    map.insert("kind".into(), self.kind().into());
                }
                serde::Serialize::serialize(&value, s)
            }
        }

        /// One closed object per kind, as its `Deserialize` reads them.
        impl schemars::JsonSchema for $name {
            fn schema_name() -> std::borrow::Cow<'static, str> {
                stringify!($name).into()
            }

            fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
                let variants = vec![$(
                    $crate::input::kinds::kinds!(
                        @schema generator, $kind, [$(#[doc = $vdoc])*], [$($inner)?],
                        [$( { $( [$(#[doc = $fdoc])* $(#[schemars($($fattr)*)])?]
                            $field : $fty ),* } )?]
                    )
                ),+];
                $crate::input::kinds::one_of_kinds($name::DESCRIPTION, variants)
            }
        }
    };
}
pub(crate) use kinds;

#[cfg(test)]
mod tests {
    use crate::input::scene::{FormulationSpec, InterfaceLawSpec, MeshSpec, ReferenceSpec};
    use serde_json::json;

    /// A value written by `Serialize` reads back the same, `kind` and keys included.
    #[test]
    fn what_is_written_reads_back() {
        for value in [
            json!({"kind": "rigid"}),
            json!({"kind": "hybrid", "penalty": 10.0}),
        ] {
            let f: FormulationSpec = serde_json::from_value(value.clone()).unwrap();
            assert_eq!(serde_json::to_value(f).unwrap(), value);
        }
        let r = json!({"kind": "bar-step", "probe": "tip"});
        let parsed: ReferenceSpec = serde_json::from_value(r.clone()).unwrap();
        assert_eq!(serde_json::to_value(&parsed).unwrap(), r);
        let law = json!({"kind": "mohr-coulomb", "tensile_strength": 1.0, "cohesion": 2.0,
            "friction_angle": 30.0});
        let parsed: InterfaceLawSpec = serde_json::from_value(law.clone()).unwrap();
        assert_eq!(parsed.kind(), "mohr-coulomb");
        assert_eq!(serde_json::to_value(parsed).unwrap(), law);
    }

    #[test]
    fn an_unknown_kind_or_key_is_refused_with_what_there_is() {
        let e = serde_json::from_value::<MeshSpec>(json!({"kind": "hexagons"})).unwrap_err();
        assert!(
            e.to_string().contains(
                "unknown kind `hexagons`, expected one of: grid, voronoi, polygons, gmsh"
            ),
            "{e}"
        );
        let e = serde_json::from_value::<FormulationSpec>(json!({"kind": "rigid", "penalty": 1}))
            .unwrap_err();
        assert!(e.to_string().contains("unknown field `penalty`"), "{e}");
    }
}
