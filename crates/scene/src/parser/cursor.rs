//! The token cursor: reads one directive's arguments (strings, numbers) and its parameter
//! list, converting each parameter's values to the type its declaration names.

use crate::error::{Loc, Result, SceneError};
use crate::lexer::{Token, TokenKind};
use crate::params::{PARAM_TYPES, Param, ParamSet, ParamValues};
use std::path::PathBuf;
use std::sync::Arc;

/// Reads one directive's arguments from a token slice.
pub(super) struct Cursor<'a> {
    pub(super) tokens: &'a [Token],
    pub(super) pos: usize,
    pub(super) file: &'a Arc<PathBuf>,
}

impl<'a> Cursor<'a> {
    pub(super) fn loc(&self, line: u32) -> Loc {
        Loc::new(self.file, line)
    }

    pub(super) fn peek(&self) -> Option<&'a Token> {
        self.tokens.get(self.pos)
    }

    fn last_line(&self) -> u32 {
        self.tokens
            .get(self.pos.saturating_sub(1))
            .map_or(1, |t| t.line)
    }

    pub(super) fn string(&mut self, directive: &str, what: &str) -> Result<String> {
        match self.peek() {
            Some(Token {
                kind: TokenKind::Str(s),
                ..
            }) => {
                self.pos += 1;
                Ok(s.clone())
            }
            _ => Err(SceneError::at(
                &self.loc(self.last_line()),
                format!("{directive} needs a quoted {what}"),
            )),
        }
    }

    fn number(&mut self, directive: &str) -> Result<f64> {
        match self.peek() {
            Some(Token {
                kind: TokenKind::Number(s),
                line,
            }) => {
                self.pos += 1;
                parse_number(s).ok_or_else(|| {
                    SceneError::at(&self.loc(*line), format!("malformed number '{s}'"))
                })
            }
            Some(t) => Err(SceneError::at(
                &self.loc(t.line),
                format!(
                    "{directive} expects a number here, found {}",
                    describe(&t.kind)
                ),
            )),
            None => Err(SceneError::at(
                &self.loc(self.last_line()),
                format!("{directive} expects more numbers, but the file ends"),
            )),
        }
    }

    /// `n` numbers, optionally inside one pair of brackets.
    pub(super) fn numbers(&mut self, directive: &str, n: usize) -> Result<Vec<f64>> {
        let bracketed = matches!(self.peek().map(|t| &t.kind), Some(TokenKind::OpenBracket));
        let open_line = self.peek().map_or(0, |t| t.line);
        if bracketed {
            self.pos += 1;
        }
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            v.push(self.number(directive)?);
        }
        if bracketed {
            match self.peek() {
                Some(Token {
                    kind: TokenKind::CloseBracket,
                    ..
                }) => self.pos += 1,
                _ => {
                    return Err(SceneError::at(
                        &self.loc(open_line),
                        format!(
                            "{directive} takes {n} numbers; the '[' here is not closed after them"
                        ),
                    ));
                }
            }
        }
        Ok(v)
    }

    /// A parameter list: `"type name" value` or `"type name" [ values ]`, repeated.
    pub(super) fn params(&mut self) -> Result<ParamSet> {
        let mut set = ParamSet::default();
        while let Some(Token {
            kind: TokenKind::Str(decl),
            line,
        }) = self.peek()
        {
            let loc = self.loc(*line);
            self.pos += 1;
            let mut words = decl.split_whitespace();
            let (Some(ty), Some(name), None) = (words.next(), words.next(), words.next()) else {
                return Err(SceneError::at(
                    &loc,
                    format!("expected a parameter declaration \"type name\", found \"{decl}\""),
                ));
            };
            if !PARAM_TYPES.contains(&ty) {
                return Err(SceneError::at(
                    &loc,
                    format!("unknown parameter type '{ty}' in \"{decl}\""),
                ));
            }
            let raw = self.values(&loc, decl)?;
            let values = convert_values(ty, name, raw, self.file)?;
            set.push(Param::new(ty, name, values, loc))?;
        }
        Ok(set)
    }

    fn values(&mut self, loc: &Loc, decl: &str) -> Result<Vec<Token>> {
        match self.peek() {
            Some(Token {
                kind: TokenKind::OpenBracket,
                ..
            }) => {
                self.pos += 1;
                let mut out = Vec::new();
                loop {
                    match self.peek() {
                        Some(Token {
                            kind: TokenKind::CloseBracket,
                            ..
                        }) => {
                            self.pos += 1;
                            return Ok(out);
                        }
                        Some(Token {
                            kind: TokenKind::OpenBracket,
                            line,
                        }) => {
                            return Err(SceneError::at(
                                &self.loc(*line),
                                format!(
                                    "unexpected '[' inside the values of \"{decl}\" (the '[' at line {} is not closed)",
                                    loc.line
                                ),
                            ));
                        }
                        Some(Token {
                            kind: TokenKind::Word(w),
                            ..
                        }) if w != "true" && w != "false" => {
                            return Err(SceneError::at(
                                loc,
                                format!(
                                    "unclosed '[' in the values of \"{decl}\" (reached '{w}' before ']')"
                                ),
                            ));
                        }
                        Some(t) => {
                            out.push(t.clone());
                            self.pos += 1;
                        }
                        None => {
                            return Err(SceneError::at(
                                loc,
                                format!(
                                    "unclosed '[' in the values of \"{decl}\": the file ends before ']'"
                                ),
                            ));
                        }
                    }
                }
            }
            Some(
                t @ Token {
                    kind: TokenKind::Number(_) | TokenKind::Str(_),
                    ..
                },
            ) => {
                self.pos += 1;
                Ok(vec![t.clone()])
            }
            Some(
                t @ Token {
                    kind: TokenKind::Word(w),
                    ..
                },
            ) if w == "true" || w == "false" => {
                self.pos += 1;
                Ok(vec![t.clone()])
            }
            _ => Err(SceneError::at(
                loc,
                format!("parameter \"{decl}\" has no value"),
            )),
        }
    }
}

pub(super) fn describe(kind: &TokenKind) -> String {
    match kind {
        TokenKind::Word(w) => format!("'{w}'"),
        TokenKind::Str(s) => format!("\"{s}\""),
        TokenKind::Number(n) => n.clone(),
        TokenKind::OpenBracket => "'['".into(),
        TokenKind::CloseBracket => "']'".into(),
    }
}

fn parse_number(s: &str) -> Option<f64> {
    s.parse::<f64>().ok().filter(|v| v.is_finite())
}

fn convert_values(
    ty: &str,
    name: &str,
    raw: Vec<Token>,
    file: &Arc<PathBuf>,
) -> Result<ParamValues> {
    let decl = format!("{ty} {name}");
    match ty {
        "string" | "texture" => raw
            .into_iter()
            .map(|t| match t.kind {
                TokenKind::Str(s) => Ok(s),
                other => Err(SceneError::at(
                    &Loc::new(file, t.line),
                    format!(
                        "\"{decl}\" needs quoted strings, found {}",
                        describe(&other)
                    ),
                )),
            })
            .collect::<Result<Vec<_>>>()
            .map(ParamValues::Strings),
        "bool" => raw
            .into_iter()
            .map(|t| match &t.kind {
                TokenKind::Word(w) | TokenKind::Str(w) if w == "true" => Ok(true),
                TokenKind::Word(w) | TokenKind::Str(w) if w == "false" => Ok(false),
                other => Err(SceneError::at(
                    &Loc::new(file, t.line),
                    format!("\"{decl}\" needs true or false, found {}", describe(other)),
                )),
            })
            .collect::<Result<Vec<_>>>()
            .map(ParamValues::Bools),
        // A spectrum is either a name (or file) or wavelength-value pairs.
        "spectrum" if matches!(raw.first().map(|t| &t.kind), Some(TokenKind::Str(_))) => {
            convert_values("string", name, raw, file)
        }
        _ => {
            let mut v = Vec::with_capacity(raw.len());
            for t in raw {
                let loc = Loc::new(file, t.line);
                let TokenKind::Number(s) = &t.kind else {
                    return Err(SceneError::at(
                        &loc,
                        format!("\"{decl}\" needs numbers, found {}", describe(&t.kind)),
                    ));
                };
                let x = parse_number(s).ok_or_else(|| {
                    SceneError::at(&loc, format!("malformed number '{s}' in \"{decl}\""))
                })?;
                if ty == "integer" && x.fract() != 0.0 {
                    return Err(SceneError::at(
                        &loc,
                        format!("\"{decl}\" needs integers, found {s}"),
                    ));
                }
                v.push(x);
            }
            Ok(ParamValues::Numbers(v))
        }
    }
}
