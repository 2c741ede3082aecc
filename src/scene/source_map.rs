//! Maps a JSON pointer to a line and column in JSON or RON text, for diagnostics.
//!
//! Load time only, and only when something is wrong: serde gives us typed data without
//! positions, so when validation finds a bad value at `/entities/3/transform/scale` we walk
//! the text once more to find where that value starts. One small walker reads both JSON and
//! RON: objects and maps (`{"key": v}`), lists (`[v, ...]`), structs and tuples
//! (`Name(field: v)`, `(a, b)`), strings, numbers and identifiers, `//` and nested `/* */`
//! comments and `#![enable(...)]` attributes.
//!
//! Rule: a named group with a single unnamed element (`Some(x)`, a newtype variant) is
//! transparent: the pointer passes through it, so `light: Some(Point(intensity: 1.0))` is
//! `/light/intensity`, exactly as serde would name the field.

use super::diagnostic::{Pointer, Segment};

/// A 1-based line and column (columns count characters, not bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Position {
    pub line: usize,
    pub column: usize,
}

/// Where the value at `pointer` starts in `text`; the deepest existing prefix of the pointer
/// when the full path is absent (a defaulted field points at its parent), or 1:1 when even
/// the root cannot be read.
pub fn locate(text: &str, pointer: &Pointer) -> Position {
    let mut cursor = Cursor {
        bytes: text.as_bytes(),
        pos: 0,
    };
    let offset = cursor.find(&pointer.0).unwrap_or(0);
    position_of(text, offset)
}

/// Line and column of a byte offset.
pub fn position_of(text: &str, offset: usize) -> Position {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let line_start = before
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    let column = String::from_utf8_lossy(&before[line_start..])
        .chars()
        .count()
        + 1;
    Position { line, column }
}

struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Cursor<'_> {
    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    /// Skips white space, comments and RON attributes (`#![...]`).
    fn skip_trivia(&mut self) {
        loop {
            match (self.peek(), self.bytes.get(self.pos + 1).copied()) {
                (Some(b' ' | b'\t' | b'\r' | b'\n'), _) => self.pos += 1,
                (Some(b'/'), Some(b'/')) => {
                    while self.peek().is_some_and(|b| b != b'\n') {
                        self.pos += 1;
                    }
                }
                (Some(b'/'), Some(b'*')) => {
                    // RON block comments nest.
                    let mut depth = 0usize;
                    while self.pos < self.bytes.len() {
                        if self.bytes[self.pos..].starts_with(b"/*") {
                            depth += 1;
                            self.pos += 2;
                        } else if self.bytes[self.pos..].starts_with(b"*/") {
                            depth -= 1;
                            self.pos += 2;
                            if depth == 0 {
                                break;
                            }
                        } else {
                            self.pos += 1;
                        }
                    }
                }
                (Some(b'#'), _) => {
                    while self.peek().is_some_and(|b| b != b'\n') {
                        self.pos += 1;
                    }
                }
                _ => return,
            }
        }
    }

    fn eat(&mut self, byte: u8) -> bool {
        self.skip_trivia();
        if self.peek() == Some(byte) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    /// Reads a scalar token (string, char, number, identifier) and returns its text
    /// (strings without quotes; escapes are kept as written, which is enough for keys).
    fn scalar(&mut self) -> Option<&str> {
        self.skip_trivia();
        let start = self.pos;
        match self.peek()? {
            quote @ (b'"' | b'\'') => {
                self.pos += 1;
                while let Some(b) = self.peek() {
                    self.pos += 1;
                    if b == b'\\' {
                        self.pos += 1;
                    } else if b == quote {
                        return std::str::from_utf8(&self.bytes[start + 1..self.pos - 1]).ok();
                    }
                }
                None
            }
            b'r' if matches!(self.bytes.get(start + 1), Some(b'"' | b'#')) => {
                // Raw string r#"..."#.
                let hashes = self.bytes[start + 1..]
                    .iter()
                    .take_while(|&&b| b == b'#')
                    .count();
                let body_start = start + 2 + hashes;
                let mut closing = vec![b'"'];
                closing.extend(std::iter::repeat_n(b'#', hashes));
                let end = self.bytes[body_start.min(self.bytes.len())..]
                    .windows(closing.len())
                    .position(|w| w == closing.as_slice())?;
                self.pos = body_start + end + closing.len();
                std::str::from_utf8(&self.bytes[body_start..body_start + end]).ok()
            }
            b if b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'+' | b'.') => {
                while self.peek().is_some_and(|b| {
                    b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'+' | b'.')
                }) {
                    self.pos += 1;
                }
                std::str::from_utf8(&self.bytes[start..self.pos]).ok()
            }
            _ => None,
        }
    }

    /// Byte offset where the value at `path` (relative to the value under the cursor)
    /// starts, or the deepest prefix found. Leaves the cursor after the current value.
    fn find(&mut self, path: &[Segment]) -> Option<usize> {
        self.skip_trivia();
        let start = self.pos;
        match self.peek()? {
            b'{' => {
                self.pos += 1;
                Some(self.map_or_struct(b'}', path).unwrap_or(start))
            }
            b'[' => {
                self.pos += 1;
                Some(self.sequence(b']', path).unwrap_or(start))
            }
            b'(' => {
                self.pos += 1;
                Some(self.group(path).unwrap_or(start))
            }
            _ => {
                let token_is_word = self
                    .scalar()
                    .is_some_and(|t| t.starts_with(|c: char| c.is_alphabetic()));
                // `Name(...)`: a struct, tuple struct or enum variant.
                if token_is_word && self.eat(b'(') {
                    return Some(self.group(path).unwrap_or(start));
                }
                Some(start)
            }
        }
    }

    /// Inside `( ... )` after the opening paren: a struct (`field: v`) or a tuple.
    fn group(&mut self, path: &[Segment]) -> Option<usize> {
        let save = self.pos;
        let is_struct = self.scalar().is_some() && self.eat(b':');
        self.pos = save;
        if is_struct {
            return self.map_or_struct(b')', path);
        }
        // Tuple: count elements first to apply the single-element transparency rule.
        let elements = self.count_elements(b')');
        if elements == 1 && !path.is_empty() && !matches!(path[0], Segment::Index(0)) {
            let found = self.find(path);
            self.close(b')');
            return found;
        }
        self.sequence(b')', path)
    }

    fn count_elements(&mut self, close: u8) -> usize {
        let save = self.pos;
        let mut count = 0;
        loop {
            self.skip_trivia();
            if self.peek().is_none() || self.eat(close) {
                break;
            }
            let before = self.pos;
            self.skip_value();
            count += 1;
            // A byte no value starts with (a stray closer) still moves the walk on.
            if !self.eat(b',') && self.pos == before {
                self.pos += 1;
            }
        }
        self.pos = save;
        count
    }

    /// Elements `v, v, ...` up to `close`; descends into element `path[0]`.
    fn sequence(&mut self, close: u8, path: &[Segment]) -> Option<usize> {
        let mut index = 0;
        let mut found = None;
        loop {
            self.skip_trivia();
            if self.peek().is_none() || self.eat(close) {
                return found;
            }
            if found.is_none() && matches!(path.first(), Some(Segment::Index(i)) if *i == index) {
                found = self.find(&path[1..]);
            } else {
                self.skip_value();
            }
            index += 1;
            if !self.eat(b',') {
                self.close(close);
                return found;
            }
        }
    }

    /// Entries `key: v, ...` up to `close`; descends into the entry named `path[0]`.
    fn map_or_struct(&mut self, close: u8, path: &[Segment]) -> Option<usize> {
        let mut found = None;
        loop {
            self.skip_trivia();
            if self.peek().is_none() || self.eat(close) {
                return found;
            }
            let key = self.scalar().map(str::to_owned);
            key.as_ref()?;
            if !self.eat(b':') {
                return found;
            }
            let matches = match (path.first(), key.as_deref()) {
                (Some(Segment::Key(wanted)), Some(key)) => wanted == key,
                (Some(Segment::Index(wanted)), Some(key)) => key.parse() == Ok(*wanted),
                _ => false,
            };
            if found.is_none() && matches {
                found = self.find(&path[1..]);
            } else {
                self.skip_value();
            }
            if !self.eat(b',') {
                self.close(close);
                return found;
            }
        }
    }

    fn close(&mut self, close: u8) {
        self.eat(close);
    }

    fn skip_value(&mut self) {
        self.skip_trivia();
        match self.peek() {
            Some(open @ (b'{' | b'[' | b'(')) => {
                let close = match open {
                    b'{' => b'}',
                    b'[' => b']',
                    _ => b')',
                };
                self.pos += 1;
                loop {
                    self.skip_trivia();
                    match self.peek() {
                        None => return,
                        Some(b) if b == close => {
                            self.pos += 1;
                            return;
                        }
                        // Separators, and a closer that does not match (`( ]`): step over
                        // them, or the walk would stand still on a broken file forever.
                        Some(b',' | b':' | b')' | b']' | b'}') => self.pos += 1,
                        Some(_) => self.skip_value(),
                    }
                }
            }
            Some(_) => {
                let is_word = self
                    .scalar()
                    .is_some_and(|t| t.starts_with(|c: char| c.is_alphabetic()));
                self.skip_trivia();
                if is_word && self.peek() == Some(b'(') {
                    self.skip_value();
                } else if !is_word
                    && self.pos < self.bytes.len()
                    && !matches!(self.peek(), Some(b',' | b')' | b']' | b'}' | b':'))
                {
                    // Unknown byte: step over it so the walk always makes progress.
                    self.pos += 1;
                }
            }
            None => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(text: &str, pointer: &str) -> (usize, usize) {
        let p = locate(text, &Pointer::parse(pointer));
        (p.line, p.column)
    }

    #[test]
    fn finds_json_values() {
        let text = "{\n  \"a\": [1, {\"b\": 2}],\n  \"c\": \"x\"\n}";
        assert_eq!(at(text, "/a/1/b"), (2, 18));
        assert_eq!(at(text, "/c"), (3, 8));
        assert_eq!(at(text, "/a/0"), (2, 9));
        // Missing: deepest prefix.
        assert_eq!(at(text, "/a/5"), (2, 8));
    }

    #[test]
    fn finds_ron_values_through_named_groups_and_some() {
        let text = "#![enable(implicit_some)]\nLevel(\n  // comment\n  entities: [\n    (name: \"a\"),\n    (name: \"b\", light: Some(Point(intensity: 2.0)), scale: (1.0, -1.0, 1.0)),\n  ],\n)";
        assert_eq!(at(text, "/entities/1/name"), (6, 12));
        assert_eq!(at(text, "/entities/1/light/intensity"), (6, 46));
        assert_eq!(at(text, "/entities/1/scale/1"), (6, 66));
        assert_eq!(at(text, "/entities/0"), (5, 5));
    }

    #[test]
    fn garbage_never_panics() {
        for text in [
            "",
            "{",
            "[[[",
            "(a: ",
            "\"unterminated",
            "r#\"x",
            "/* open",
            "{\"a\" 1}",
            "\u{1F600}",
        ] {
            let _ = at(text, "/a/0/b");
        }
    }

    /// Found by fuzzing levels: a stray closer inside a group (`( ]`) stood the walk still
    /// and `check` (and so the editor's reload) never returned.
    #[test]
    fn a_stray_closer_cannot_stall_the_walk() {
        for text in [
            "(a: ( ] ), b: 1)",
            "(a: [ ) ], b: 1)",
            "(a: { ] }, b: 1)",
            "( ] ] ] )",
            "(a: (}), b: (]), c: 3)",
        ] {
            let position = locate(text, &Pointer::parse("/b"));
            assert!(position.line >= 1, "{text}");
        }
    }
}
