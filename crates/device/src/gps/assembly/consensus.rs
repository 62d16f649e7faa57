//! The position of an epoch whose sentences disagree ([`consensus`]).

use super::{Kind, LatLon};

/// The most position sentences one epoch keeps for [`consensus`] (a receiver sends at most GGA, RMC, GLL,
/// GNS and a proprietary one per second; a stream repeating one second's sentences keeps its last ones).
pub(super) const MAX_EPOCH_POSITIONS: usize = 8;

/// Two position sentences of one epoch agree when they are at most this far apart: more than NMEA's
/// rounding (0.0001′ is 0.19 m) and the small differences of a receiver that computes each sentence
/// separately (under 0.7 m on the B&G Zeus²), less than one second of walking (1.4 m).
pub(super) const AGREE_M: f64 = 1.0;

/// Metres per degree of latitude (mean), for [`AGREE_M`]'s flat-earth comparison.
pub(super) const M_PER_DEG: f64 = 111_195.0;

/// The position an epoch reports, chosen from its sentences' positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Consensus {
    /// The position with the most sentences within [`AGREE_M`] of it.
    pub(super) position: Option<LatLon>,
    /// The kinds (bits of [`Kind`]) of the sentences more than [`AGREE_M`] from the chosen position: 0
    /// when all agree (counted in [`DecodeStats::disagreeing_positions`]).
    pub(super) outvoted: u16,
}

/// NMEA 0183 ties a sentence to its epoch by its UTC field, so an epoch's GGA, RMC, GLL and GNS describe
/// one instant and agree. A multiplexer that mislabels one of them (the B&G Zeus² labels GGA one second
/// earlier than RMC and ZDA for a while, and GLL moves from GGA's label to RMC's) gives an epoch two
/// positions a second of motion apart. The position most sentences give is the epoch's. On a tie, the
/// sentence kinds the last disagreement out-voted (`outvoted_before`, bits of [`Kind`]) lose: they are the
/// mislabelled ones. Then, as when all agree, the latest sentence's (docs/gps.md, "`bundg_zeus_9`").
pub(super) fn consensus(positions: &[(Kind, LatLon)], outvoted_before: u16) -> Consensus {
    let agree = |a: LatLon, b: LatLon| {
        let north = (a.0 - b.0) * M_PER_DEG;
        let east = ((a.1 - b.1 + 540.0).rem_euclid(360.0) - 180.0) * M_PER_DEG * a.0.to_radians().cos();
        north * north + east * east <= AGREE_M * AGREE_M
    };
    let trusted = |kind: Kind| outvoted_before & (1 << kind as u16) == 0;
    let mut best: Option<((usize, bool), LatLon)> = None;
    for &(kind, p) in positions {
        let support = positions.iter().filter(|&&(_, q)| agree(p, q)).count();
        let rank = (support, trusted(kind));
        if best.is_none_or(|(r, _)| rank >= r) {
            best = Some((rank, p));
        }
    }
    let Some((_, position)) = best else { return Consensus { position: None, outvoted: 0 } };
    let outvoted =
        positions.iter().filter(|&&(_, q)| !agree(position, q)).fold(0, |bits, &(k, _)| bits | 1 << k as u16);
    Consensus { position: Some(position), outvoted }
}
