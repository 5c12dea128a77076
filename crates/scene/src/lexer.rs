//! Splits pbrt-v4 scene text into tokens, each with its line.

use crate::error::{Loc, Result, SceneError};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Debug, Clone, PartialEq)]
pub enum TokenKind {
    /// A bare word: a directive name, or `true`/`false`.
    Word(String),
    /// A quoted string, without its quotes.
    Str(String),
    /// A number, kept as text until its parameter type is known.
    Number(String),
    OpenBracket,
    CloseBracket,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Token {
    pub kind: TokenKind,
    pub line: u32,
}

/// Tokenises a whole file. Errors (an unterminated string, a stray character) name the line.
pub fn tokenize(text: &str, file: &Arc<PathBuf>) -> Result<Vec<Token>> {
    let mut tokens = Vec::new();
    let bytes = text.as_bytes();
    let mut i = 0;
    let mut line = 1u32;
    while i < bytes.len() {
        let c = bytes[i];
        match c {
            b'\n' => {
                line += 1;
                i += 1;
            }
            b' ' | b'\t' | b'\r' | b',' => i += 1,
            b'#' => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'[' => {
                tokens.push(Token {
                    kind: TokenKind::OpenBracket,
                    line,
                });
                i += 1;
            }
            b']' => {
                tokens.push(Token {
                    kind: TokenKind::CloseBracket,
                    line,
                });
                i += 1;
            }
            b'"' => {
                let start_line = line;
                let start = i + 1;
                let mut j = start;
                let mut value = String::new();
                loop {
                    if j >= bytes.len() || bytes[j] == b'\n' {
                        return Err(SceneError::at(
                            &Loc::new(file, start_line),
                            "unterminated string (a '\"' is missing before the end of the line)",
                        ));
                    }
                    match bytes[j] {
                        b'"' => break,
                        b'\\' if j + 1 < bytes.len() => {
                            let escaped = match bytes[j + 1] {
                                b'n' => '\n',
                                b't' => '\t',
                                other => other as char,
                            };
                            value.push(escaped);
                            j += 2;
                        }
                        _ => {
                            // Copy a whole UTF-8 character at once.
                            let ch_len = utf8_len(bytes[j]);
                            let end = (j + ch_len).min(bytes.len());
                            value.push_str(&String::from_utf8_lossy(&bytes[j..end]));
                            j = end;
                        }
                    }
                }
                tokens.push(Token {
                    kind: TokenKind::Str(value),
                    line: start_line,
                });
                i = j + 1;
            }
            _ => {
                let start = i;
                while i < bytes.len()
                    && !matches!(
                        bytes[i],
                        b' ' | b'\t' | b'\r' | b'\n' | b'[' | b']' | b'"' | b'#' | b','
                    )
                {
                    i += 1;
                }
                let word = String::from_utf8_lossy(&bytes[start..i]).into_owned();
                let first = word.as_bytes()[0];
                let kind =
                    if first.is_ascii_digit() || first == b'-' || first == b'+' || first == b'.' {
                        TokenKind::Number(word)
                    } else if first.is_ascii_alphabetic() || first == b'_' {
                        TokenKind::Word(word)
                    } else {
                        return Err(SceneError::at(
                            &Loc::new(file, line),
                            format!("unexpected character '{word}'"),
                        ));
                    };
                tokens.push(Token { kind, line });
            }
        }
    }
    Ok(tokens)
}

fn utf8_len(first: u8) -> usize {
    match first {
        0x00..=0x7f => 1,
        0xc0..=0xdf => 2,
        0xe0..=0xef => 3,
        _ => 4,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(text: &str) -> Vec<TokenKind> {
        tokenize(text, &Arc::new(PathBuf::from("t.pbrt")))
            .unwrap()
            .into_iter()
            .map(|t| t.kind)
            .collect()
    }

    #[test]
    fn splits_directives_strings_numbers_and_brackets() {
        let k = kinds("Shape \"sphere\" \"float radius\" [ 1.5 ] # comment\nWorldBegin");
        assert_eq!(
            k,
            vec![
                TokenKind::Word("Shape".into()),
                TokenKind::Str("sphere".into()),
                TokenKind::Str("float radius".into()),
                TokenKind::OpenBracket,
                TokenKind::Number("1.5".into()),
                TokenKind::CloseBracket,
                TokenKind::Word("WorldBegin".into()),
            ]
        );
    }

    #[test]
    fn brackets_need_no_spaces_and_lines_are_counted() {
        let toks = tokenize("A\n\n[1 -2e3]", &Arc::new(PathBuf::from("t"))).unwrap();
        assert_eq!(toks[1].line, 3);
        assert_eq!(toks[2].kind, TokenKind::Number("1".into()));
        assert_eq!(toks[3].kind, TokenKind::Number("-2e3".into()));
    }

    #[test]
    fn unterminated_string_names_its_line() {
        let err = tokenize("A\nB \"oops\n", &Arc::new(PathBuf::from("s.pbrt"))).unwrap_err();
        assert!(err.to_string().starts_with("s.pbrt:2:"), "{err}");
    }
}
