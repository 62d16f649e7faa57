//! The replies of a receiver being configured: UBX ACK-ACK/ACK-NAK and `SiRF` MID 11/12, read from the
//! frames the GPS framer ([`crate::gps::framing::Framer`], the one home of NMEA/UBX/`SiRF` framing) hands
//! out with their checksums verified.

use crate::gps::framing::Frame;

/// A reply that confirms or refuses a configuration command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reply {
    /// UBX-ACK-ACK for `class`/`id` (UBX-13003221 §32.9.2: class 0x05 id 0x01, payload `clsID msgID`).
    UbxAck {
        /// Class of the acknowledged message.
        class: u8,
        /// Id of the acknowledged message.
        id: u8,
    },
    /// UBX-ACK-NAK for `class`/`id` (§32.9.1: class 0x05 id 0x00, same payload).
    UbxNak {
        /// Class of the refused message.
        class: u8,
        /// Id of the refused message.
        id: u8,
    },
    /// `SiRF` MID 11 Command Acknowledgment of `mid`.
    SirfAck {
        /// The acknowledged MID.
        mid: u8,
    },
    /// `SiRF` MID 12 Command `NAcknowledgment` of `mid`.
    SirfNak {
        /// The refused MID.
        mid: u8,
    },
}

/// The reply a frame carries, if it is one (payloads shorter than the layout are not replies).
pub fn reply(frame: &Frame<'_>) -> Option<Reply> {
    match *frame {
        Frame::Ubx { class: super::UBX_ACK, id, payload } if payload.len() == 2 => {
            let (class, msg) = (payload[0], payload[1]);
            match id {
                super::UBX_ACK_ACK => Some(Reply::UbxAck { class, id: msg }),
                super::UBX_ACK_NAK => Some(Reply::UbxNak { class, id: msg }),
                _ => None,
            }
        }
        Frame::Sirf { payload: p } if p.len() >= 2 => match p[0] {
            super::SIRF_MID_ACK => Some(Reply::SirfAck { mid: p[1] }),
            super::SIRF_MID_NACK => Some(Reply::SirfNak { mid: p[1] }),
            _ => None,
        },
        _ => None,
    }
}
