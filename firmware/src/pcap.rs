//! The capture's UDP datagrams: a classic pcap (little-endian, microseconds) of Ethernet II,
//! IPv4 and UDP frames, walked in place (the tools read pcaps with `pcap-file` and `etherparse`;
//! here no_std, a few lines).

/// A datagram of a classic pcap (Ethernet, IPv4, UDP): its destination port and payload.
/// Little-endian microsecond pcaps only (the capture's); anything else ends the walk.
pub(crate) fn datagrams(pcap: &[u8], mut f: impl FnMut(u16, &[u8])) {
    if pcap.len() < 24 || pcap[..4] != [0xd4, 0xc3, 0xb2, 0xa1] {
        return;
    }
    let mut at = 24;
    while let Some(head) = pcap.get(at..at + 16) {
        let caplen = u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as usize;
        let Some(frame) = pcap.get(at + 16..at + 16 + caplen) else {
            return;
        };
        at += 16 + caplen;
        // Ethernet II, IPv4 (its header length), UDP.
        if frame.len() < 14 + 20 || frame[12..14] != [0x08, 0x00] || frame[14 + 9] != 17 {
            continue;
        }
        let ip_len = usize::from(frame[14] & 0x0f) * 4;
        let udp = 14 + ip_len;
        let Some(h) = frame.get(udp..udp + 8) else {
            continue;
        };
        let port = u16::from_be_bytes([h[2], h[3]]);
        let len = usize::from(u16::from_be_bytes([h[4], h[5]])).saturating_sub(8);
        if let Some(payload) = frame.get(udp + 8..udp + 8 + len) {
            f(port, payload);
        }
    }
}
