//! The conformance suite's client of the unit: raw frames over the PTY, spoken with the codec's framing
//! (`vestnav_device::wtcu::codec`).

use super::*;

pub(super) struct Client {
    pub(super) port: Box<dyn serialport::SerialPort>,
    pub(super) codec: FrameCodec,
    pub(super) seq: u8,
    /// Unsolicited replies received (REPORT, HEADING, `GPS_DATA`), with their arrival.
    pub(super) unsolicited: Vec<(Instant, Packet<Reply>)>,
    /// Every answer received, with its seq (to find repeats and stray answers).
    pub(super) answers: Vec<Packet<Reply>>,
    pub(super) last_sent: Instant,
}

pub(super) fn is_unsolicited(r: &Reply) -> bool {
    matches!(r, Reply::Report { .. } | Reply::Heading(_) | Reply::GpsData { .. })
}

impl Client {
    pub(super) fn open(path: &str) -> Self {
        let port = serialport::new(path, 115_200).timeout(Duration::from_millis(5)).open().unwrap();
        // Whatever the unit said before we opened (its boot, a previous client) is not ours.
        std::thread::sleep(Duration::from_millis(50));
        let _ = port.clear(serialport::ClearBuffer::Input);
        Self {
            port,
            codec: FrameCodec::new(),
            seq: 0,
            unsolicited: Vec::new(),
            answers: Vec::new(),
            last_sent: Instant::now(),
        }
    }

    pub(super) fn send_raw(&mut self, bytes: &[u8]) {
        self.port.write_all(bytes).unwrap();
        self.port.flush().unwrap();
        self.last_sent = Instant::now();
    }

    pub(super) fn next_seq(&mut self) -> u8 {
        self.seq = self.seq.wrapping_add(1);
        self.seq
    }

    /// Reads for up to `d`, sorting what arrives; stops early once `until` holds for an answer.
    pub(super) fn read_for(
        &mut self,
        d: Duration,
        until: impl Fn(&Packet<Reply>) -> bool,
    ) -> Option<Packet<Reply>> {
        let end = Instant::now() + d;
        let mut buf = [0u8; 512];
        while Instant::now() < end {
            let n = match self.port.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => 0,
                Err(e) => panic!("reading the unit: {e}"),
            };
            let mut out = Vec::new();
            self.codec.decode_replies(&buf[..n], &mut out);
            let now = Instant::now();
            let mut hit = None;
            for packet in out.into_iter().flatten() {
                if is_unsolicited(&packet.message) {
                    self.unsolicited.push((now, packet));
                } else {
                    self.answers.push(packet.clone());
                    if hit.is_none() && until(&packet) {
                        hit = Some(packet);
                    }
                }
            }
            if hit.is_some() {
                return hit;
            }
        }
        None
    }

    /// Sends `request` in a `version` header and waits for its answer.
    pub(super) fn ask_v(&mut self, version: u8, request: &Request) -> Result<Packet<Reply>, String> {
        let seq = self.next_seq();
        self.codec.set_version(version);
        let frame = self.codec.encode_request(seq, request).unwrap();
        self.send_raw(&frame);
        self.read_for(Duration::from_millis(500), |p| p.seq == seq)
            .ok_or_else(|| format!("no answer to {request:?} (seq {seq}) within 500 ms"))
    }

    pub(super) fn ask(&mut self, request: &Request) -> Result<Packet<Reply>, String> {
        self.ask_v(2, request)
    }

    /// Waits `d` while keeping the unit's watchdog fed (a HEARTBEAT every 250 ms).
    pub(super) fn idle(&mut self, d: Duration) {
        let end = Instant::now() + d;
        while Instant::now() < end {
            if self.last_sent.elapsed() >= Duration::from_millis(250) {
                let seq = self.next_seq();
                self.codec.set_version(2);
                let frame = self.codec.encode_request(seq, &Request::Heartbeat).unwrap();
                self.send_raw(&frame);
            }
            self.read_for(
                Duration::from_millis(10).min(end.saturating_duration_since(Instant::now())),
                |_| false,
            );
        }
    }

    /// Waits `d` sending nothing.
    pub(super) fn silent(&mut self, d: Duration) {
        self.read_for(d, |_| false);
    }

    pub(super) fn hello(&mut self) -> Result<DeviceInfo, String> {
        match self.ask(&Request::Hello)?.message {
            Reply::Identify(info) => Ok(info),
            other => Err(format!("HELLO answered with {other:?}")),
        }
    }
}

pub(super) fn ack(reply: &Packet<Reply>) -> Result<TactorMask, String> {
    match reply.message {
        Reply::Ack { tactors_on } => Ok(tactors_on),
        ref other => Err(format!("expected ACK, got {other:?}")),
    }
}

pub(super) fn nak(reply: &Packet<Reply>, want: NakReason) -> Check {
    match reply.message {
        Reply::Nak { reason, .. } if reason == want => Ok(()),
        ref other => Err(format!("expected NAK {want} (0x{:02X}), got {other:?}", want.code())),
    }
}

pub(super) fn fire(mask: u16, duration_ms: u16) -> Request {
    Request::Fire { mask: TactorMask(mask), duration_ms }
}

/// A frame built by hand (header version, type, seq, payload), with a correct or deliberately wrong CRC.
pub(super) fn raw_frame(version: u8, kind: u8, seq: u8, payload: &[u8], corrupt_crc: bool) -> Vec<u8> {
    let mut packet = vec![version, kind, seq, payload.len() as u8];
    packet.extend_from_slice(payload);
    let mut crc = vestnav_device::wtcu::codec::CRC16.checksum(&packet);
    if corrupt_crc {
        crc ^= 0x5A5A;
    }
    packet.extend_from_slice(&crc.to_le_bytes());
    let mut out = vec![0];
    cobs_encode(&packet, &mut out);
    out.push(0);
    out
}
