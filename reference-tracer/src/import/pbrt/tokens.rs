//! pbrt's tokens: quoted strings, numbers and names, brackets, `#` comments, each with
//! the line it starts on.

use std::path::Path;

use super::error_at;
use crate::scene::SceneError;

/// One token and the line it starts on.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Token {
    /// A bare word or number.
    Word(String),
    /// A quoted string, without its quotes.
    Quoted(String),
    Open,
    Close,
}

pub(super) struct Tokens {
    tokens: Vec<(Token, usize)>,
    next: usize,
}

pub(super) fn tokenize(file: &Path, text: &str) -> Result<Tokens, SceneError> {
    let mut tokens = Vec::new();
    let mut chars = text.char_indices().peekable();
    let mut line = 1;
    while let Some((_, c)) = chars.next() {
        match c {
            '\n' => line += 1,
            c if c.is_whitespace() => {}
            '#' => {
                for (_, c) in chars.by_ref() {
                    if c == '\n' {
                        line += 1;
                        break;
                    }
                }
            }
            '[' => tokens.push((Token::Open, line)),
            ']' => tokens.push((Token::Close, line)),
            '"' => {
                let start = line;
                let mut value = String::new();
                loop {
                    match chars.next() {
                        None => return Err(error_at(file, start, "unterminated string")),
                        Some((_, '"')) => break,
                        Some((_, '\n')) => return Err(error_at(file, start, "string runs past the end of its line")),
                        Some((_, '\\')) => match chars.next() {
                            Some((_, 'n')) => value.push('\n'),
                            Some((_, 't')) => value.push('\t'),
                            Some((_, c)) => value.push(c),
                            None => return Err(error_at(file, start, "unterminated string")),
                        },
                        Some((_, c)) => value.push(c),
                    }
                }
                tokens.push((Token::Quoted(value), start));
            }
            c => {
                let mut word = String::from(c);
                while let Some(&(_, c)) = chars.peek() {
                    if c.is_whitespace() || matches!(c, '[' | ']' | '"' | '#') {
                        break;
                    }
                    word.push(c);
                    chars.next();
                }
                tokens.push((Token::Word(word), line));
            }
        }
    }
    Ok(Tokens { tokens, next: 0 })
}

impl Tokens {
    pub(super) fn peek(&self) -> Option<&(Token, usize)> {
        self.tokens.get(self.next)
    }

    pub(super) fn take(&mut self) -> Option<(Token, usize)> {
        let token = self.tokens.get(self.next).cloned();
        self.next += token.is_some() as usize;
        token
    }

    pub(super) fn line(&self) -> usize {
        self.tokens.get(self.next.saturating_sub(1)).map_or(1, |t| t.1)
    }
}
