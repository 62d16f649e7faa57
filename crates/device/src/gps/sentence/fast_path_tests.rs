//! The own GGA/GLL/RMC/GSA fast paths against the `nmea` crate: same result or decline.

use super::*;
use crate::gps::framing::with_checksum;
use proptest::prelude::*;

/// Splits a sentence the way [`parse`] does: the fields after the tag.
fn fields(sentence: &str) -> Vec<&str> {
    sentence[1..sentence.len() - 3].split(',').skip(1).collect()
}

/// Whether the fast path took the sentence (and then agreed with the crate).
fn agrees(sentence: &str) -> bool {
    let f = fields(sentence);
    let fast = match sentence.get(3..6) {
        Some("GGA") => fast_gga(sentence, &f),
        Some("GLL") => fast_gll(sentence, &f),
        Some("RMC") => fast_rmc(sentence, &f),
        _ => fast_gsa(sentence, &sentence[1..3], &f),
    };
    if let Some(fast) = fast {
        assert_eq!(Ok(fast), via_crate(sentence, &sentence[1..3]), "{sentence}");
        return true;
    }
    false
}

/// The own GGA/GLL/RMC/GSA decoding equals the `nmea` crate's on every such sentence of gpsd's logs.
#[test]
fn fast_path_matches_the_crate_on_gpsd_logs() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs");
    let (mut checked, mut fast) = (0, 0);
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "log") {
            continue;
        }
        let text = String::from_utf8_lossy(&std::fs::read(path).unwrap()).into_owned();
        for line in text.lines().map(str::trim_end) {
            let Some(start) = line.find('$') else { continue };
            let s = &line[start..];
            if s.len() > 10
                && s.is_ascii()
                && s.as_bytes()[s.len() - 3] == b'*'
                && !s[1..].contains('$')
                && with_checksum(&s[1..s.len() - 3]).trim_end() == s
            {
                let kind = &s[3..6];
                if matches!(kind, "GGA" | "GLL" | "RMC" | "GSA") {
                    fast += usize::from(agrees(s));
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 1000, "{checked}");
    assert!(fast * 10 > checked * 9, "the fast path took only {fast} of {checked}");
}

proptest! {
    /// Random near-canonical GGA, GLL, RMC and GSA: the fast path either declines or agrees with the crate.
    #[test]
    fn fast_path_matches_the_crate(
        time in "[0-9]{6}(\\.[0-9]{1,4})?|[0-9]{5}|",
        lat in "[0-9]{4}(\\.[0-9]{1,6})?|[0-9]{2}\\.|",
        ns in "[NSX]?",
        lon in "[0-9]{5}(\\.[0-9]{1,6})?|",
        ew in "[EWX]?",
        q in "[0-9]?",
        sats in "[0-9]{0,3}",
        hdop in "[0-9]{1,2}(\\.[0-9]{1,3})?|-1|",
        alt in "-?[0-9]{1,5}(\\.[0-9]{1,3})?|",
        sep in "-?[0-9]{1,3}(\\.[0-9]{1,2})?|",
        status in "[AVX]",
        mode in "[ADNX]?",
        date in "[0-3][0-9][01][0-9][0-9]{2}|[0-9]{5}|",
        m1 in "[MAX]",
        ids in proptest::collection::vec("[0-9]{0,3}", 12..14),
        sys in "(,[0-9]{0,2})?",
    ) {
        let gga = format!("GPGGA,{time},{lat},{ns},{lon},{ew},{q},{sats},{hdop},{alt},M,{sep},M,,");
        let _ = agrees(with_checksum(&gga).trim_end());
        let gll = format!("GPGLL,{lat},{ns},{lon},{ew},{time},{status},{mode}");
        let _ = agrees(with_checksum(&gll).trim_end());
        let rmc = format!("GNRMC,{time},{status},{lat},{ns},{lon},{ew},{hdop},{sep},{date},{hdop},{ew},{mode}");
        let _ = agrees(with_checksum(&rmc).trim_end());
        let gsa = format!("GPGSA,{m1},{q},{},{hdop},{sep},{alt}{sys}", ids.join(","));
        let _ = agrees(with_checksum(&gsa).trim_end());
    }
}
