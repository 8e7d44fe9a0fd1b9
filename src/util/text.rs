//! Text helpers shared by the command parser and the method names.

/// ASCII case-insensitive word comparison, kept out of line: the parser compares a word
/// with some 25 keywords, and inlining the comparison loop at each of them costs flash.
#[inline(never)]
pub fn keyword_eq(word: &str, keyword: &str) -> bool {
    word.eq_ignore_ascii_case(keyword)
}
