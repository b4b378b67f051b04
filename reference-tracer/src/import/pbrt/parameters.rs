//! A directive's typed parameter list (`"float fov" [45]`) and its typed lookups.

use std::path::Path;

use super::error_at;
use super::tokens::{Token, Tokens};
use crate::scene::SceneError;

#[derive(Clone, Debug, PartialEq)]
pub(super) enum Values {
    Numbers(Vec<f32>),
    Strings(Vec<String>),
}

/// One `"type name" value…` of a parameter list.
#[derive(Clone, Debug)]
pub(super) struct Parameter {
    pub(super) kind: String,
    pub(super) name: String,
    pub(super) values: Values,
    /// The line it is written on.
    pub(super) line: usize,
}

/// A directive's parameter list, with lookups that name the directive's line in errors.
#[derive(Clone, Debug, Default)]
pub(super) struct Parameters {
    pub(super) list: Vec<Parameter>,
    pub(super) line: usize,
}

impl Parameters {
    pub(super) fn find(&self, name: &str) -> Option<&Parameter> {
        self.list.iter().find(|p| p.name == name)
    }

    pub(super) fn numbers(&self, file: &Path, name: &str) -> Result<Option<&[f32]>, SceneError> {
        match self.find(name) {
            None => Ok(None),
            Some(Parameter { values: Values::Numbers(v), .. }) => Ok(Some(v)),
            Some(p) => Err(error_at(file, p.line, format!("\"{} {name}\" must hold numbers", p.kind))),
        }
    }

    pub(super) fn float(&self, file: &Path, name: &str, default: f32) -> Result<f32, SceneError> {
        match self.numbers(file, name)? {
            None => Ok(default),
            Some([v]) => Ok(*v),
            Some(_) => {
                Err(error_at(file, self.find(name).map_or(self.line, |p| p.line), format!("`{name}` takes one number")))
            }
        }
    }

    pub(super) fn string(&self, file: &Path, name: &str) -> Result<Option<&str>, SceneError> {
        match self.find(name) {
            None => Ok(None),
            Some(Parameter { values: Values::Strings(v), .. }) if v.len() == 1 => Ok(Some(&v[0])),
            Some(p) => Err(error_at(file, p.line, format!("`{name}` takes one string"))),
        }
    }

    pub(super) fn boolean(&self, file: &Path, name: &str, default: bool) -> Result<bool, SceneError> {
        match self.string(file, name)? {
            None => Ok(default),
            Some("true") => Ok(true),
            Some("false") => Ok(false),
            Some(other) => Err(error_at(file, self.line, format!("`{name}` is \"{other}\", expected true or false"))),
        }
    }

    /// An RGB colour (`rgb`/`color`, or one number for a grey `float`), or a texture's name.
    pub(super) fn color_or_texture(&self, file: &Path, name: &str) -> Result<Option<ColorOrTexture>, SceneError> {
        let Some(p) = self.find(name) else { return Ok(None) };
        match (p.kind.as_str(), &p.values) {
            ("rgb" | "color", Values::Numbers(v)) if v.len() == 3 => {
                Ok(Some(ColorOrTexture::Color([v[0], v[1], v[2]])))
            }
            ("float", Values::Numbers(v)) if v.len() == 1 => Ok(Some(ColorOrTexture::Color([v[0]; 3]))),
            ("texture", Values::Strings(v)) if v.len() == 1 => Ok(Some(ColorOrTexture::Texture(v[0].clone()))),
            ("spectrum" | "blackbody", _) => Err(error_at(
                file,
                p.line,
                format!("\"{} {name}\": spectral values are not supported; give \"rgb {name}\"", p.kind),
            )),
            _ => Err(error_at(file, p.line, format!("\"{} {name}\" must be an RGB colour or a texture", p.kind))),
        }
    }

    pub(super) fn rgb(&self, file: &Path, name: &str) -> Result<Option<[f32; 3]>, SceneError> {
        match self.color_or_texture(file, name)? {
            None => Ok(None),
            Some(ColorOrTexture::Color(c)) => Ok(Some(c)),
            Some(ColorOrTexture::Texture(_)) => {
                Err(error_at(file, self.line, format!("`{name}` must be a colour here, not a texture")))
            }
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub(super) enum ColorOrTexture {
    Color([f32; 3]),
    Texture(String),
}

pub(super) fn parse_parameters(file: &Path, tokens: &mut Tokens) -> Result<Parameters, SceneError> {
    let mut parameters = Parameters { list: Vec::new(), line: tokens.line() };
    while let Some((Token::Quoted(_), _)) = tokens.peek() {
        let Some((Token::Quoted(declaration), line)) = tokens.take() else { unreachable!() };
        let mut words = declaration.split_whitespace();
        let (Some(kind), Some(name), None) = (words.next(), words.next(), words.next()) else {
            return Err(error_at(file, line, format!("parameter \"{declaration}\" is not \"type name\"")));
        };
        let (kind, name) = (kind.to_string(), name.to_string());
        let mut raw = Vec::new();
        match tokens.take() {
            Some((Token::Open, _)) => loop {
                match tokens.take() {
                    Some((Token::Close, _)) => break,
                    Some((Token::Open, l)) => return Err(error_at(file, l, "nested `[`")),
                    Some((token, _)) => raw.push(token),
                    None => return Err(error_at(file, line, format!("`{name}`: unterminated `[`"))),
                }
            },
            Some((token @ (Token::Word(_) | Token::Quoted(_)), _)) => raw.push(token),
            _ => return Err(error_at(file, line, format!("`{name}` has no value"))),
        }
        let numeric = matches!(
            kind.as_str(),
            "float"
                | "integer"
                | "point"
                | "point3"
                | "normal"
                | "normal3"
                | "vector"
                | "vector3"
                | "rgb"
                | "color"
                | "point2"
                | "vector2"
                | "blackbody"
                | "spectrum"
        ) && raw.iter().all(|t| matches!(t, Token::Word(_)));
        let values = if numeric {
            let numbers: Result<Vec<f32>, _> = raw
                .iter()
                .map(|t| match t {
                    Token::Word(w) => w.parse::<f32>().map_err(|_| w.clone()),
                    _ => Err(String::new()),
                })
                .collect();
            Values::Numbers(numbers.map_err(|w| error_at(file, line, format!("`{name}`: \"{w}\" is not a number")))?)
        } else {
            Values::Strings(
                raw.into_iter()
                    .map(|t| match t {
                        Token::Word(w) | Token::Quoted(w) => w,
                        _ => String::new(),
                    })
                    .collect(),
            )
        };
        if let Values::Numbers(v) = &values {
            if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
                return Err(error_at(file, line, format!("`{name}`: {bad} is not finite")));
            }
        }
        parameters.list.push(Parameter { kind, name, values, line });
    }
    Ok(parameters)
}
