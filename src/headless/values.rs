//! The number checks of every run's options, one per kind of quantity: clap runs them while it
//! parses, so a bad value is one line naming the flag and the range (`invalid value '-3'
//! for '--spp <SPP>': -3 is not in 1..=4294967295`). Negative numbers are read as values
//! (each command allows them), so `--spp -3` is judged by the range rather than taken
//! for an unknown flag.

/// A count of one or more.
pub fn count() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..)
}

/// A count that may be zero.
pub fn count_or_zero() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(0..)
}

/// A size (threads, triangles) of one or more.
pub fn size() -> clap::builder::RangedI64ValueParser<usize> {
    clap::builder::RangedI64ValueParser::<usize>::new().range(1..)
}

/// A size that may be zero.
pub fn size_or_zero() -> clap::builder::RangedI64ValueParser<usize> {
    clap::builder::RangedI64ValueParser::<usize>::new().range(0..)
}

fn number<T: std::str::FromStr + Into<f64> + Copy>(
    text: &str,
    accept: impl Fn(f64) -> bool,
    range: &str,
) -> Result<T, String> {
    let value: T = text
        .parse()
        .map_err(|_| format!("'{text}' is not a number"))?;
    if accept(value.into()) {
        Ok(value)
    } else {
        Err(format!("must be {range}"))
    }
}

/// Greater than zero (seconds, milliseconds, metres, a multiplier).
pub fn positive(text: &str) -> Result<f64, String> {
    number(text, |v| v.is_finite() && v > 0.0, "a number above 0")
}

/// As `positive`, single precision.
pub fn positive_f32(text: &str) -> Result<f32, String> {
    number(text, |v| v.is_finite() && v > 0.0, "a number above 0")
}

/// A place, `X,Y,Z` in metres (three finite numbers).
pub fn point(text: &str) -> Result<glam::Vec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [x, y, z] = parts[..] else {
        return Err(format!(
            "'{text}' is not X,Y,Z (three numbers separated by commas)"
        ));
    };
    let coordinate = |part: &str| match part.parse::<f32>() {
        Ok(value) if value.is_finite() => Ok(value),
        _ => Err(format!("'{part}' in '{text}' is not a finite number")),
    };
    Ok(glam::Vec3::new(
        coordinate(x)?,
        coordinate(y)?,
        coordinate(z)?,
    ))
}

/// Any finite number (an angle).
pub fn finite(text: &str) -> Result<f32, String> {
    number(text, f64::is_finite, "a finite number")
}

/// Zero or more (a time, a wait).
pub fn non_negative(text: &str) -> Result<f64, String> {
    number(text, |v| v.is_finite() && v >= 0.0, "a number of 0 or more")
}

/// Between 0 and 1 inclusive (a gem value, a blend weight).
pub fn unit(text: &str) -> Result<f32, String> {
    number(text, |v| (0.0..=1.0).contains(&v), "between 0 and 1")
}

/// Above 0 and at most 1 (a scale per axis, a blend weight that must not vanish).
pub fn share(text: &str) -> Result<f32, String> {
    number(text, |v| v > 0.0 && v <= 1.0, "above 0 and at most 1")
}
