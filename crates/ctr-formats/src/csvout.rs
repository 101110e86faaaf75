//! The output side of the CSV files, written straight into byte buffers: fields with
//! the csv crate's quoting (only where needed) and floats in Rust's shortest round-trip
//! form, without a heap allocation per value.
//!
//! Both are exactly what `csv::Writer` and `format!("{v}")` write (the tests compare
//! them); they are here because a million-row job spends most of its time writing.

/// Appends `field` as one CSV field: as it is, or in double quotes (inner quotes
/// doubled) when it holds a comma, a double quote, `\r` or `\n` — the csv crate's
/// `QuoteStyle::Necessary` with its default delimiter and terminator.
pub(crate) fn write_field(out: &mut Vec<u8>, field: &str) {
    let bytes = field.as_bytes();
    if !bytes
        .iter()
        .any(|b| matches!(b, b',' | b'"' | b'\r' | b'\n'))
    {
        out.extend_from_slice(bytes);
        return;
    }
    out.push(b'"');
    for &b in bytes {
        if b == b'"' {
            out.push(b'"');
        }
        out.push(b);
    }
    out.push(b'"');
}

/// Appends a record's fields separated by commas and ends the line (`\n`).
pub(crate) fn write_record<'a>(out: &mut Vec<u8>, fields: impl IntoIterator<Item = &'a str>) {
    for (k, f) in fields.into_iter().enumerate() {
        if k > 0 {
            out.push(b',');
        }
        write_field(out, f);
    }
    out.push(b'\n');
}

/// Appends `v` exactly as `format!("{v}")` writes it: the shortest digits that parse
/// back to the same `f64`, laid out without an exponent (`100`, `0.001`, `-0`,
/// `1e-7` as `0.0000001`; `NaN`, `inf`, `-inf`).
///
/// The digits come from the `ryu` crate: like Rust's own formatter it finds the shortest
/// digits that round trip and, of those, the closest to `v`; the two break an exact tie
/// between two closest differently (ryu to even, Rust up). A tie needs `v` to be exactly
/// a decimal of at most 18 significant digits (half way between two of 17 or fewer),
/// so such values, and only those, are left to Rust's formatter. Only the layout is
/// done here.
pub(crate) fn write_float(out: &mut Vec<u8>, v: f64) {
    if !v.is_finite() {
        out.extend_from_slice(if v.is_nan() {
            b"NaN"
        } else if v > 0.0 {
            b"inf"
        } else {
            b"-inf"
        });
        return;
    }
    if v == 0.0 {
        out.extend_from_slice(if v.is_sign_negative() { b"-0" } else { b"0" });
        return;
    }
    if is_short_decimal(v) {
        use std::io::Write;
        // writing to a Vec cannot fail
        let _ = write!(out, "{v}");
        return;
    }
    if v.is_sign_negative() {
        out.push(b'-');
    }
    let mut buf = ryu::Buffer::new();
    let text = buf.format_finite(v.abs()).as_bytes();
    // ryu writes `ddd.ddd` and `0.000ddd` as Rust does; only `ddd.0` and the
    // exponent forms need a new layout
    if !text.contains(&b'e') {
        match text.strip_suffix(b".0") {
            Some(int) => out.extend_from_slice(int),
            None => out.extend_from_slice(text),
        }
        return;
    }
    // ryu writes `d.ddd`, `ddd.0`, `0.000ddd` or `d.ddde-N` / `de+N` forms: collect the
    // significant digits and where the decimal point falls among them
    let (mantissa, exp10) = match text.iter().position(|&b| b == b'e') {
        Some(e) => (&text[..e], parse_exponent(&text[e + 1..])),
        None => (text, 0),
    };
    let mut digits = [0u8; 24];
    let mut len = 0;
    let mut int_len: i32 = 0;
    let mut seen_point = false;
    let mut leading = true;
    for &b in mantissa {
        if b == b'.' {
            seen_point = true;
            continue;
        }
        if !seen_point {
            int_len += 1;
        }
        if leading && b == b'0' {
            // a leading zero moves the point, it is not a digit
            int_len -= 1;
            continue;
        }
        leading = false;
        digits[len] = b;
        len += 1;
    }
    while len > 1 && digits[len - 1] == b'0' {
        len -= 1;
    }
    let digits = &digits[..len];
    // v = 0.digits * 10^point
    let point = int_len + exp10;
    let len = len as i32;
    if point <= 0 {
        out.extend_from_slice(b"0.");
        out.extend(std::iter::repeat_n(b'0', (-point) as usize));
        out.extend_from_slice(digits);
    } else if point < len {
        out.extend_from_slice(&digits[..point as usize]);
        out.push(b'.');
        out.extend_from_slice(&digits[point as usize..]);
    } else {
        out.extend_from_slice(digits);
        out.extend(std::iter::repeat_n(b'0', (point - len) as usize));
    }
}

/// True when the finite, non-zero `v` is exactly a decimal of at most 18 significant
/// digits: `v = m 2^e` with `m` odd has the digits of `m 2^e` (`e >= 0`) or of
/// `m 5^-e` (`e < 0`).
fn is_short_decimal(v: f64) -> bool {
    const LIMIT: u128 = 1_000_000_000_000_000_000;
    let bits = v.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1 << 52) - 1);
    let (mut m, mut e) = if biased == 0 {
        (fraction, -1074)
    } else {
        (fraction | (1 << 52), biased - 1075)
    };
    let tz = m.trailing_zeros();
    m >>= tz;
    e += tz as i32;
    if e >= 0 {
        // 2^60 > 10^18
        e < 60 && (u128::from(m) << e) < LIMIT
    } else {
        // 5^26 > 10^18
        -e <= 26 && u128::from(m) * 5u128.pow((-e) as u32) < LIMIT
    }
}

fn parse_exponent(text: &[u8]) -> i32 {
    let (sign, digits) = match text.first() {
        Some(b'-') => (-1, &text[1..]),
        Some(b'+') => (1, &text[1..]),
        _ => (1, text),
    };
    sign * digits
        .iter()
        .fold(0i32, |acc, &d| acc * 10 + i32::from(d - b'0'))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn float(v: f64) -> String {
        let mut out = Vec::new();
        write_float(&mut out, v);
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn floats_are_written_as_rusts_display() {
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            100.0,
            0.1,
            0.3,
            0.1 + 0.2,
            1e-7,
            1.5e-7,
            123456.789,
            1e15,
            1e16,
            1.2345e17,
            1e21,
            1e22,
            1e23,
            9007199254740993.0,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            f64::EPSILON,
            5e-324,
            -5e-324,
            // the largest subnormal
            f64::from_bits(0x000f_ffff_ffff_ffff),
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            4.0657581468206416e-20,
            std::f64::consts::PI,
            -180.0,
            359.99999999999994,
        ];
        for v in special {
            assert_eq!(float(v), format!("{v}"), "{v:e}");
        }
        // every exponent, random mantissas (xorshift)
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let count = if cfg!(debug_assertions) {
            200_000
        } else {
            2_000_000
        };
        for k in 0..count {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let bits = match k % 4 {
                // short decimals: trailing zeros
                0 => ((x % 2_000_000) as f64 / 1000.0 - 1000.0).to_bits(),
                // large values with few fraction bits: exact ties
                1 => ((x >> 11) as f64 / f64::from(1u32 << (x % 8))).to_bits(),
                _ => x,
            };
            let v = f64::from_bits(bits);
            assert_eq!(float(v), format!("{v}"), "{bits:#x}");
        }
    }

    #[test]
    fn fields_are_quoted_as_the_csv_crate_does() {
        let fields = [
            "plain",
            "",
            " spaced ",
            "a,b",
            "say \"hi\"",
            "line\nbreak",
            "cr\rhere",
            "ünïcödé",
            "#hash",
            "'single'",
            "tab\there",
        ];
        let mut ours = Vec::new();
        write_record(&mut ours, fields);
        write_record(&mut ours, ["x", ""]);
        let mut w = csv::WriterBuilder::new()
            .flexible(true)
            .from_writer(Vec::new());
        w.write_record(fields).unwrap();
        w.write_record(["x", ""]).unwrap();
        assert_eq!(
            String::from_utf8(ours).unwrap(),
            String::from_utf8(w.into_inner().unwrap()).unwrap()
        );
    }
}
