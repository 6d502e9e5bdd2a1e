//! The checks every model makes of its scene parameters (with the error hints), and the
//! elasticity pair of the solids. The parameters as written do not depend on the precision:
//! [`MaterialParams`] (in `table.rs`).

use super::constitutive::ModelInfo;
pub use super::table::{MaterialParams, ParamError};
use crate::math::Real;
use serde::Deserialize;

/// The error of an unknown `type`.
pub(super) fn unknown_kind(kind: &str, all: &[ModelInfo]) -> ParamError {
    let names: Vec<String> = all.iter().map(|m| format!("\"{}\"", m.name)).collect();
    ParamError::new(
        "type",
        format!("unknown material type \"{kind}\""),
        format!("use one of {}", names.join(", ")),
    )
}

/// `x`, finite.
pub fn finite(field: &str, x: f32) -> Result<Real, ParamError> {
    if x.is_finite() {
        Ok(x as Real)
    } else {
        Err(ParamError::new(
            field,
            format!("{x} is not a finite number"),
            "write a finite number",
        ))
    }
}

/// `x`, finite and > 0; `what` names it in the message.
pub fn positive(field: &str, x: f32, what: &str) -> Result<Real, ParamError> {
    let v = finite(field, x)?;
    if x > 0.0 {
        Ok(v)
    } else {
        Err(ParamError::new(
            field,
            format!("{what} must be > 0, got {x}"),
            format!("give a positive {what}"),
        ))
    }
}

/// `x` (or `default` when absent), finite and >= 0.
pub fn non_negative(
    field: &str,
    x: Option<f32>,
    default: f32,
    what: &str,
) -> Result<Real, ParamError> {
    let x = x.unwrap_or(default);
    let v = finite(field, x)?;
    if x >= 0.0 {
        Ok(v)
    } else {
        Err(ParamError::new(
            field,
            format!("{what} must be >= 0, got {x}"),
            format!("use 0 or a positive {what}"),
        ))
    }
}

/// A required field: its value, or the error "a `kind` material needs `field` (`unit`)".
pub fn required(field: &str, x: Option<f32>, kind: &str, example: &str) -> Result<f32, ParamError> {
    x.ok_or_else(|| {
        ParamError::new(
            field,
            format!("a {kind} material needs `{field}`"),
            format!("add it, e.g. {field} = {example}"),
        )
    })
}

/// The elasticity of a solid, written as Young's modulus and Poisson's ratio or as the Lamé
/// parameters (one pair, not both). Each solid's parameter struct has these four fields.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Elasticity {
    pub youngs_modulus: Option<f32>,
    pub poisson_ratio: Option<f32>,
    pub mu: Option<f32>,
    pub lambda: Option<f32>,
}

impl Elasticity {
    /// Checked Lamé parameters `(mu, lambda)`.
    pub fn lame(&self) -> Result<(Real, Real), ParamError> {
        match (
            self.youngs_modulus,
            self.poisson_ratio,
            self.mu,
            self.lambda,
        ) {
            (Some(e), Some(nu), None, None) => {
                let e = positive("youngs_modulus", e, "Young's modulus (Pa)")?;
                finite("poisson_ratio", nu)?;
                if nu >= 0.5 {
                    return Err(ParamError::new(
                        "poisson_ratio",
                        format!(
                            "Poisson's ratio must be below 0.5, got {nu} (incompressible: lambda is infinite)"
                        ),
                        "use nu < 0.5 (e.g. 0.45 for rubbery jelly), or a type = \"fluid\" material for liquids",
                    ));
                }
                if nu <= -1.0 {
                    return Err(ParamError::new(
                        "poisson_ratio",
                        format!("Poisson's ratio must be above -1, got {nu}"),
                        "use a value in (-1, 0.5), typically 0.2-0.4",
                    ));
                }
                Ok(super::constitutive::lame(e, nu as Real))
            }
            (None, None, Some(mu), Some(lambda)) => {
                let mu_r = positive("mu", mu, "shear modulus mu (Pa)")?;
                let lambda_r = finite("lambda", lambda)?;
                if lambda + 2.0 / 3.0 * mu <= 0.0 {
                    return Err(ParamError::new(
                        "lambda",
                        format!(
                            "lambda = {lambda} gives a non-positive bulk modulus lambda + 2 mu / 3"
                        ),
                        "use lambda > -2 mu / 3 (usually lambda > 0)",
                    ));
                }
                Ok((mu_r, lambda_r))
            }
            (e, nu, mu, lambda) => {
                let field = if e.is_some() && nu.is_none() {
                    "poisson_ratio"
                } else if nu.is_some() && e.is_none() {
                    "youngs_modulus"
                } else if mu.is_some() && lambda.is_none() {
                    "lambda"
                } else if (lambda.is_some() && mu.is_none()) || e.is_some() {
                    "mu"
                } else {
                    "youngs_modulus"
                };
                Err(ParamError::new(
                    field,
                    "give the elasticity as youngs_modulus + poisson_ratio, or as mu + lambda (one pair, not both)",
                    "e.g. youngs_modulus = 3e5, poisson_ratio = 0.3",
                ))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct P {
        a: f32,
        #[allow(dead_code)]
        b: Option<f32>,
    }

    #[test]
    fn unknown_missing_and_mistyped_fields_name_the_field() {
        let e = MaterialParams::parse("x", "a = 1\nc = 2")
            .unwrap()
            .deserialize::<P>()
            .unwrap_err();
        assert_eq!(e.field, "c");
        assert!(e.hint.contains("`a`"), "{e}");
        let e = MaterialParams::parse("x", "b = 2")
            .unwrap()
            .deserialize::<P>()
            .unwrap_err();
        assert_eq!(e.field, "a");
        let e = MaterialParams::parse("x", "a = \"one\"")
            .unwrap()
            .deserialize::<P>()
            .unwrap_err();
        assert!(e.message.contains("string"), "{e}");
        let p: P = MaterialParams::parse("x", "a = 3")
            .unwrap()
            .deserialize()
            .unwrap();
        assert_eq!(p.a, 3.0);
    }

    #[test]
    fn elasticity_pairs() {
        let el = |s: &str| {
            MaterialParams::parse("x", s)
                .unwrap()
                .deserialize::<Elasticity>()
                .unwrap()
                .lame()
        };
        let (mu, lambda) = el("youngs_modulus = 2.6\npoisson_ratio = 0.3").unwrap();
        assert!((mu - 1.0).abs() < 1e-6 && (lambda - 1.5).abs() < 1e-5);
        assert_eq!(el("mu = 1\nlambda = 2").unwrap(), (1.0, 2.0));
        assert_eq!(el("youngs_modulus = 1").unwrap_err().field, "poisson_ratio");
        assert_eq!(el("mu = 1").unwrap_err().field, "lambda");
        assert_eq!(
            el("youngs_modulus = 1\npoisson_ratio = 0.5")
                .unwrap_err()
                .field,
            "poisson_ratio"
        );
        assert_eq!(el("mu = 1\nlambda = -1").unwrap_err().field, "lambda");
    }
}
