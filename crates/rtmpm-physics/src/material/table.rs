//! A material's parameters as written in a scene: the model name and the model's own fields of a
//! `[[material]]` table, read into the model's serde struct (each model's `Params`). They do not
//! depend on the precision: the f64 package uses these types of the f32 package, and each
//! precision builds its model from them.

/// Why a material's parameters were refused: the field (relative to the `[[material]]` table),
/// what is wrong, and how to fix it. The scene validator adds the table's path and line.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamError {
    /// Field name, e.g. `poisson_ratio` (`type` for an unknown model).
    pub field: String,
    /// What is wrong.
    pub message: String,
    /// How to fix it.
    pub hint: String,
}

impl ParamError {
    /// An error of `field`.
    pub fn new(field: &str, message: impl Into<String>, hint: impl Into<String>) -> ParamError {
        ParamError {
            field: field.to_string(),
            message: message.into(),
            hint: hint.into(),
        }
    }
}

impl std::fmt::Display for ParamError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "`{}`: {} ({})", self.field, self.message, self.hint)
    }
}

impl std::error::Error for ParamError {}

/// The model name (`type`) and the model's own fields of a `[[material]]` table, as written
/// (precision-independent: every precision builds its model from them).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialParams {
    /// The model, e.g. `fluid`.
    pub kind: String,
    /// Every field of the table but `name`, `type` and `density`.
    pub fields: toml::Table,
}

impl MaterialParams {
    /// From TOML text of the fields, e.g. `MaterialParams::parse("fluid", "bulk_modulus = 1e5")`.
    pub fn parse(kind: &str, fields: &str) -> Result<MaterialParams, ParamError> {
        let fields: toml::Table = toml::from_str(fields).map_err(|e| {
            ParamError::new(
                "",
                format!("not a TOML table: {}", e.message()),
                "write the fields as `name = value` lines",
            )
        })?;
        Ok(MaterialParams {
            kind: kind.to_string(),
            fields,
        })
    }

    /// The fields read into a model's parameter struct `P` (unknown fields and wrong types are
    /// errors naming the field).
    pub fn deserialize<P: serde::de::DeserializeOwned>(&self) -> Result<P, ParamError> {
        P::deserialize(toml::Value::Table(self.fields.clone())).map_err(|e| {
            let message = e.message().trim().to_string();
            if let Some(f) = backticked(&message, "unknown field ") {
                ParamError::new(
                    f,
                    format!("`{f}` is not a parameter of a {} material", self.kind),
                    format!(
                        "remove it or fix its spelling; {}",
                        message
                            .split_once(", expected ")
                            .map(|(_, list)| format!("this type takes {list}"))
                            .unwrap_or_else(|| "see docs/scene-format.md".into())
                    ),
                )
            } else if let Some(f) = backticked(&message, "missing field ") {
                ParamError::new(
                    f,
                    format!("a {} material needs `{f}`", self.kind),
                    "add the field (docs/scene-format.md lists its unit and typical values)",
                )
            } else if let Some(v) = backticked(&message, "unknown variant ") {
                let field = self
                    .fields
                    .iter()
                    .find(|(_, x)| x.as_str() == Some(v))
                    .map_or("", |(k, _)| k.as_str());
                ParamError::new(field, message.clone(), "use one of the listed values")
            } else {
                let field = self.fields.keys().find(|k| message.contains(k.as_str()));
                ParamError::new(
                    field.map_or("", |s| s.as_str()),
                    message,
                    "check the value's type: numbers without quotes, names in quotes",
                )
            }
        })
    }
}

/// The name in backticks right after `prefix` in a serde message, e.g. the field of
/// "unknown field `x`, expected ...".
pub fn backticked<'m>(message: &'m str, prefix: &str) -> Option<&'m str> {
    let rest = &message[message.find(prefix)? + prefix.len()..];
    let rest = rest.strip_prefix('`')?;
    Some(&rest[..rest.find('`')?])
}
