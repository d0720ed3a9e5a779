//! Bytes as hex text and back: the one spelling every front end prints (`52 47 11 00 2C 30`) and the
//! spellings it reads (`52 47`, `5247`, `0x52,0x47`, `52:47`, `52-47`).

/// Formats bytes as spaced upper-case hex: `[0x52, 0x0a]` is `52 0A`.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        s.push_str(&format!("{b:02X}"));
    }
    s
}

/// Parses hex bytes: pairs of digits, optionally separated by whitespace (line breaks too), `,`, `:` or
/// `-`, each optionally prefixed with `0x`. An error names the word that is not hex bytes.
pub fn parse_hex(text: &str) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    for token in text.split(|c: char| c.is_whitespace() || matches!(c, ',' | ':' | '-')).filter(|t| !t.is_empty()) {
        let digits = token.strip_prefix("0x").or_else(|| token.strip_prefix("0X")).unwrap_or(token);
        if digits.len() % 2 != 0 || !digits.chars().all(|c| c.is_ascii_hexdigit()) {
            return Err(format!("{token:?} is not hex bytes (expected pairs of hex digits such as 52 47 or 5247)"));
        }
        for i in (0..digits.len()).step_by(2) {
            bytes.push(u8::from_str_radix(&digits[i..i + 2], 16).map_err(|e| e.to_string())?);
        }
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_accepts_common_spellings() {
        assert_eq!(parse_hex("52 47 0x11,00:A3-0e\n5247").unwrap(), vec![0x52, 0x47, 0x11, 0, 0xA3, 0x0E, 0x52, 0x47]);
        assert_eq!(parse_hex("").unwrap(), Vec::<u8>::new());
    }

    #[test]
    fn hex_rejects_odd_digits_and_non_hex() {
        assert!(parse_hex("524").unwrap_err().contains("\"524\" is not hex bytes"));
        assert!(parse_hex("zz").is_err());
    }

    #[test]
    fn hex_formats_spaced_upper_case() {
        assert_eq!(hex(&[0x52, 0x0a]), "52 0A");
        assert_eq!(hex(&[]), "");
    }
}
