//! When a session was recorded, from its id: OptiOdom names a session folder by the local time
//! its recording started, `DDMMYYYYhhmm` (230620202042 is 23 June 2020, 20:42; the dates in the
//! shared data's README agree). An id of another shape, or one that is not a valid date and time,
//! has no recording time: the session is then undated, never guessed.

/// The recording time of session `id` in days since 1970-01-01 00:00 (fractional: the time of
/// day is in it), or `None` when `id` is not a valid `DDMMYYYYhhmm`.
pub fn recorded_days(id: &str) -> Option<f64> {
    let digits = id.as_bytes();
    if digits.len() != 12 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let field = |from: usize, len: usize| -> i64 {
        digits[from..from + len]
            .iter()
            .fold(0, |n, d| n * 10 + i64::from(d - b'0'))
    };
    let (day, month, year) = (field(0, 2), field(2, 2), field(4, 4));
    let (hour, minute) = (field(8, 2), field(10, 2));
    if !(1..=12).contains(&month) || day < 1 || day > days_in_month(year, month) {
        return None;
    }
    if hour > 23 || minute > 59 {
        return None;
    }
    let days = days_from_civil(year, month, day);
    Some(days as f64 + (hour * 60 + minute) as f64 / 1440.0)
}

fn is_leap(year: i64) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

fn days_in_month(year: i64, month: i64) -> i64 {
    match month {
        2 if is_leap(year) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// Days from 1970-01-01 to the given date of the proleptic Gregorian calendar (the civil-date
/// algorithm: years counted from March, so that the leap day ends a year).
fn days_from_civil(year: i64, month: i64, day: i64) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let year_of_era = y - era * 400;
    let month_from_march = (month + 9) % 12;
    let day_of_year = (153 * month_from_march + 2) / 5 + day - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    era * 146_097 + day_of_era - 719_468
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shared_sessions_ids_are_their_recording_times() {
        // 1970-01-01 is day 0; 2000-03-01 is day 11017 (a leap century's leap day before it).
        assert_eq!(recorded_days("010119700000"), Some(0.0));
        assert_eq!(recorded_days("010320000000"), Some(11_017.0));
        assert_eq!(recorded_days("290220000000"), Some(11_016.0));
        // 23 June 2020 20:42 to 23 December 2020 00:29: 183 days less 20 h 13 min.
        let june = recorded_days("230620202042").unwrap();
        let december = recorded_days("231220200029").unwrap();
        assert!((december - june - (183.0 - (20.0 * 60.0 + 13.0) / 1440.0)).abs() < 1e-9);
        // 3 January 2021 00:01 is 11 days after 23 December 2020 00:01.
        let january = recorded_days("030120210001").unwrap();
        let dec_0001 = recorded_days("231220200001").unwrap();
        assert!((january - dec_0001 - 11.0).abs() < 1e-9);
    }

    #[test]
    fn an_id_that_is_not_a_valid_date_is_undated() {
        for id in [
            "",
            "23122020002",
            "2312202000291",
            "23122020002x",
            "321220200029",
            "001220200029",
            "231320200029",
            "290220210000",
            "290219000000",
            "231220202400",
            "231220200060",
            "session-1",
        ] {
            assert_eq!(recorded_days(id), None, "{id}");
        }
    }
}
