//! Numbers a scene may hold (issue 66): every number in a scene file is finite and at most
//! `MAX_MAGNITUDE` in size, whatever field it is in, so that no value becomes infinite after its
//! conversion to SI (the largest factor is 1e9, GPa) or in the products the build forms from a
//! few of them. A NaN body offset, a modulus of 1e300 GPa or a pivot 1e300 mm away were accepted
//! by `check` and failed in `run`. The check reads the text, so its errors give the line and
//! column, and the field name before the number. NaN and infinities are refused before the
//! build (which would otherwise fail on them with a misleading message: a NaN offset made a
//! selection "select no vertex"); magnitudes after it, whose own range checks say more where
//! they apply ("outside +-1000 m").

/// The largest magnitude any number in a scene may have, in any unit: far above every physical
/// quantity a skin scene holds (and a u64 seed, 1.8e19), far below what overflows f64 after
/// a few products (1e308).
pub const MAX_MAGNITUDE: f64 = 1e30;

/// The first number of `text` (RON) that is NaN, infinite or above `MAX_MAGNITUDE` in size:
/// its 1-based line and column, its text, and the nearest field name before it (`young` in
/// `young: 1e300`, `size` in `size: (8.0, 2e31)`). Strings and comments are skipped.
pub fn unbounded_number(text: &str) -> Option<Unbounded> {
    first_number(text, |v| !v.is_finite() || v.abs() > MAX_MAGNITUDE)
}

/// The first number of `text` that is NaN or infinite (`1e999` too), as `unbounded_number`.
pub fn non_finite_number(text: &str) -> Option<Unbounded> {
    first_number(text, |v| !v.is_finite())
}

/// A number found: its 1-based line and column, its text, the field name before it.
pub type Unbounded = (usize, usize, String, Option<String>);

fn first_number(text: &str, bad: impl Fn(f64) -> bool) -> Option<Unbounded> {
    let chars: Vec<char> = text.chars().collect();
    let (mut i, mut line, mut col) = (0usize, 1usize, 1usize);
    let mut key: Option<String> = None;
    // Moves up to character `to`, keeping the line and column.
    let advance = |i: &mut usize, line: &mut usize, col: &mut usize, to: usize| {
        while *i < to.min(chars.len()) {
            if chars.get(*i) == Some(&'\n') {
                *line += 1;
                *col = 1;
            } else {
                *col += 1;
            }
            *i += 1;
        }
    };
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '"' {
            // a string: to its closing quote, past escapes
            let mut j = i + 1;
            while j < chars.len() && chars[j] != '"' {
                j += if chars[j] == '\\' { 2 } else { 1 };
            }
            advance(&mut i, &mut line, &mut col, j + 1);
        } else if c == '/' && next == Some('/') {
            let end = chars[i..].iter().position(|&x| x == '\n').map_or(chars.len(), |k| i + k);
            advance(&mut i, &mut line, &mut col, end);
        } else if c == '/' && next == Some('*') {
            let end = (i + 2..chars.len().saturating_sub(1)).find(|&k| chars[k] == '*' && chars[k + 1] == '/');
            advance(&mut i, &mut line, &mut col, end.map_or(chars.len(), |k| k + 2));
        } else if c.is_alphabetic() || c == '_' {
            let len = chars[i..].iter().take_while(|x| x.is_alphanumeric() || **x == '_').count();
            let word: String = chars[i..i + len].iter().collect();
            if ["nan", "inf", "infinity"].contains(&word.to_ascii_lowercase().as_str()) {
                let signed = i > 0 && matches!(chars[i - 1], '-' | '+');
                let (l, c0) = if signed { (line, col - 1) } else { (line, col) };
                let shown = if signed { format!("{}{word}", chars[i - 1]) } else { word };
                return Some((l, c0, shown, key));
            }
            if chars[i + len..].iter().find(|c| !c.is_whitespace()) == Some(&':') {
                key = Some(word);
            }
            let to = i + len;
            advance(&mut i, &mut line, &mut col, to);
        } else if c.is_ascii_digit() || (matches!(c, '-' | '+' | '.') && next.is_some_and(|n| n.is_ascii_digit())) {
            let mut j = i + 1;
            while j < chars.len() {
                let x = chars[j];
                let exponent_sign = matches!(x, '-' | '+') && matches!(chars[j - 1], 'e' | 'E');
                if x.is_ascii_alphanumeric() || x == '.' || x == '_' || exponent_sign {
                    j += 1;
                } else {
                    break;
                }
            }
            let token: String = chars[i..j].iter().collect();
            let value = token.replace('_', "").parse::<f64>();
            if value.is_ok_and(&bad) {
                return Some((line, col, token, key));
            }
            advance(&mut i, &mut line, &mut col, j);
        } else {
            let to = i + 1;
            advance(&mut i, &mut line, &mut col, to);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_what_no_quantity_can_be_with_its_place() {
        let ok = "Scene(name: \"a 1e999 b\", // 1e400\n  young: 1.5e6, seed: 18446744073709551615, x2: -3e-7, /* NaN */ k: 1_000.5)";
        assert_eq!(unbounded_number(ok), None);
        let at = |l, c, t: &str, k: &str| Some((l, c, t.to_string(), Some(k.to_string())));
        assert_eq!(unbounded_number("(a: 1,\n  young: 1e300)"), at(2, 10, "1e300", "young"));
        assert_eq!(unbounded_number("(offset: NaN)"), at(1, 10, "NaN", "offset"));
        assert_eq!(unbounded_number("(offset: -inf)"), at(1, 10, "-inf", "offset"));
        assert_eq!(unbounded_number("(p: (0.0, 1e31, 0))"), at(1, 11, "1e31", "p"));
        assert_eq!(unbounded_number("(p: -2.5e+40)"), at(1, 5, "-2.5e+40", "p"));
        assert_eq!(unbounded_number("[1e99]").map(|r| r.3), Some(None));
        // (an identifier's digits are not a number; hex integers stay what they are)
        assert_eq!(unbounded_number("(layer9: 0xff, s: \"x\\\"1e99\")"), None);
    }
}
