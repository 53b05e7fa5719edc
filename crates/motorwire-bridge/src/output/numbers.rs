//! Numbers as the bridge says them: an f32 from the wire printed as its
//! shortest decimal.

/// The f64 whose shortest decimal is `f`'s (so `0.1f32` prints `0.1`, not
/// `0.10000000149011612`); `None` when `f` is not finite. Formatted on the
/// stack: nothing is allocated.
pub(crate) fn f32_shortest(f: f32) -> Option<f64> {
    use std::io::Write;
    if !f.is_finite() {
        return None;
    }
    // The longest f32 Display is under 50 bytes (`-0.000000000000000000000000000000000000000000001`).
    let mut buf = [0u8; 64];
    let len = {
        let mut w = &mut buf[..];
        write!(w, "{f}").ok()?;
        64 - w.len()
    };
    std::str::from_utf8(buf.get(..len)?).ok()?.parse().ok()
}

/// `v` as the shortest decimal of the f32 it came from, when it is one
/// (iRPC carries f32: `45.29999923706055` prints as `45.3`); `v` otherwise.
pub(crate) fn shortest(v: f64) -> f64 {
    #[allow(clippy::cast_possible_truncation)]
    let f = v as f32;
    if f64::from(f) == v {
        f32_shortest(f).unwrap_or(v)
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::f32_shortest;

    #[test]
    fn an_f32_becomes_the_f64_of_its_shortest_decimal() {
        assert_eq!(f32_shortest(0.1), Some(0.1));
        assert_eq!(f32_shortest(-123.456), Some(-123.456));
        assert_eq!(f32_shortest(f32::MAX), Some(3.402_823_5e38));
        // The longest Display an f32 has: the smallest subnormal, 1e-45.
        assert_eq!(f32_shortest(-f32::from_bits(1)), Some(-1e-45));
        assert_eq!(f32_shortest(f32::NAN), None);
        assert_eq!(f32_shortest(f32::INFINITY), None);
    }
}
