//! Frames <-> UDP datagrams: the lax slicer readers use (real captures carry IPv4 lengths that
//! do not match the frame: PROTOCOLS.md) and the frame builder writers use.

use crate::packet::SkipReason;
use etherparse::{EtherType, LaxNetSlice, LaxSlicedPacket, TransportSlice};
use pcap_file::DataLink;
use std::io;
use std::net::Ipv4Addr;

/// The frame's network and transport layers below its link layer (`link`: the capture's
/// LINKTYPE), laxly.
fn sliced(link: u32, frame: &[u8]) -> Result<LaxSlicedPacket<'_>, SkipReason> {
    Ok(match DataLink::from(link) {
        DataLink::ETHERNET => {
            LaxSlicedPacket::from_ethernet(frame).map_err(|_| SkipReason::NotIpv4Udp)?
        }
        DataLink::RAW | DataLink::IPV4 => {
            LaxSlicedPacket::from_ip(frame).map_err(|_| SkipReason::NotIpv4Udp)?
        }
        DataLink::NULL | DataLink::LOOP => {
            LaxSlicedPacket::from_ip(frame.get(4..).ok_or(SkipReason::NotIpv4Udp)?)
                .map_err(|_| SkipReason::NotIpv4Udp)?
        }
        DataLink::LINUX_SLL => {
            let proto = frame.get(14..16).ok_or(SkipReason::NotIpv4Udp)?;
            LaxSlicedPacket::from_ether_type(
                EtherType(u16::from_be_bytes([proto[0], proto[1]])),
                &frame[16..],
            )
        }
        DataLink::LINUX_SLL2 => {
            let proto = frame.get(0..2).ok_or(SkipReason::NotIpv4Udp)?;
            let rest = frame.get(20..).ok_or(SkipReason::NotIpv4Udp)?;
            LaxSlicedPacket::from_ether_type(
                EtherType(u16::from_be_bytes([proto[0], proto[1]])),
                rest,
            )
        }
        _ => return Err(SkipReason::UnsupportedLinkType(link)),
    })
}

/// Link layer -> IPv4 -> UDP, laxly; the payload runs to the UDP length or the captured end.
pub fn slice_udp(link: u32, frame: &[u8]) -> Result<(Ipv4Addr, u16, u16, &[u8]), SkipReason> {
    let sliced = sliced(link, frame)?;
    let Some(LaxNetSlice::Ipv4(ip)) = &sliced.net else {
        return Err(SkipReason::NotIpv4Udp);
    };
    let h = ip.header();
    if h.is_fragmenting_payload() {
        return Err(SkipReason::IpFragment);
    }
    let Some(TransportSlice::Udp(udp)) = &sliced.transport else {
        return Err(SkipReason::NotIpv4Udp);
    };
    // Where the UDP header sits in the frame: the payload is cut by the UDP length, not by the
    // IPv4 total length (which some recorders fill with a canned value).
    let udp_at = udp.slice().as_ptr() as usize - frame.as_ptr() as usize;
    let after = &frame[udp_at + 8..];
    let udp_len = usize::from(udp.length());
    let payload = if udp_len >= 8 && udp_len - 8 <= after.len() {
        &after[..udp_len - 8]
    } else {
        after
    };
    Ok((
        h.source_addr(),
        udp.source_port(),
        udp.destination_port(),
        payload,
    ))
}

/// One fragment of an IPv4 datagram (RFC 791): its datagram's key, where its bytes go in the
/// datagram's payload, whether more follow, its bytes.
#[derive(Debug, Clone, Copy)]
pub struct Fragment<'a> {
    /// Sender.
    pub src: Ipv4Addr,
    /// Receiver.
    pub dst: Ipv4Addr,
    /// The datagram's identification.
    pub id: u16,
    /// The payload's protocol (17: UDP).
    pub protocol: u8,
    /// Byte offset in the datagram's payload (the header's fragment offset x 8).
    pub offset: usize,
    /// "More fragments".
    pub more: bool,
    /// The bytes.
    pub payload: &'a [u8],
}

/// The IPv4 fragment `frame` carries (`None`: not an IPv4 fragment).
pub fn slice_fragment(link: u32, frame: &[u8]) -> Option<Fragment<'_>> {
    let sliced = sliced(link, frame).ok()?;
    let Some(LaxNetSlice::Ipv4(ip)) = &sliced.net else {
        return None;
    };
    let h = ip.header();
    if !h.is_fragmenting_payload() {
        return None;
    }
    Some(Fragment {
        src: h.source_addr(),
        dst: h.destination_addr(),
        id: h.identification(),
        protocol: h.protocol().0,
        offset: usize::from(h.fragments_offset().value()) * 8,
        more: h.more_fragments(),
        payload: ip.payload().payload,
    })
}

/// Addresses of a sensor's UDP frames (VLP-16 factory defaults: 192.168.1.201 broadcasting to
/// 255.255.255.255, source MAC 60:76:88 Velodyne OUI).
#[derive(Debug, Clone, Copy)]
pub struct UdpEndpoints {
    /// Source MAC.
    pub src_mac: [u8; 6],
    /// Destination MAC.
    pub dst_mac: [u8; 6],
    /// Source IPv4.
    pub src_ip: [u8; 4],
    /// Destination IPv4.
    pub dst_ip: [u8; 4],
}

impl Default for UdpEndpoints {
    fn default() -> Self {
        Self {
            src_mac: [0x60, 0x76, 0x88, 0x10, 0x20, 0x30],
            dst_mac: [0xFF; 6],
            src_ip: [192, 168, 1, 201],
            dst_ip: [255, 255, 255, 255],
        }
    }
}

/// Bytes of IP payload a fragment carries on a 1500-byte Ethernet link (the MTU less the
/// 20-byte IPv4 header; a multiple of 8, as every fragment but the last must be).
pub const FRAGMENT_BYTES: usize = 1480;

/// One piece of a UDP datagram fragmented for the link ([`udp_fragments`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Piece<'a> {
    /// Byte offset in the IP payload (the UDP header and the datagram's payload).
    pub offset: usize,
    /// More pieces follow.
    pub more: bool,
    /// The UDP header the first piece begins with (source and destination port, length,
    /// checksum 0: none, as IPv4 allows).
    pub udp_header: Option<[u8; 8]>,
    /// Its share of the datagram's payload.
    pub payload: &'a [u8],
}

/// The pieces of the UDP datagram (`src_port` -> `dst_port`, `payload`) in IPv4 fragments of
/// [`FRAGMENT_BYTES`] as a sender on a 1500-byte link cuts it (RFC 791 3.2); one piece, whole,
/// when it fits. `None` when it is too long for UDP (65,507 bytes).
pub fn udp_fragments(
    src_port: u16,
    dst_port: u16,
    payload: &[u8],
) -> Option<impl Iterator<Item = Piece<'_>>> {
    let len = u16::try_from(payload.len() + 8)
        .ok()
        .filter(|&l| l <= 65_515)?;
    let mut h = [0u8; 8];
    h[0..2].copy_from_slice(&src_port.to_be_bytes());
    h[2..4].copy_from_slice(&dst_port.to_be_bytes());
    h[4..6].copy_from_slice(&len.to_be_bytes());
    let total = usize::from(len);
    Some((0..total.div_ceil(FRAGMENT_BYTES)).map(move |k| {
        let (a, b) = (k * FRAGMENT_BYTES, ((k + 1) * FRAGMENT_BYTES).min(total));
        Piece {
            offset: a,
            more: b < total,
            udp_header: (k == 0).then_some(h),
            payload: &payload[a.saturating_sub(8)..b - 8],
        }
    }))
}

/// Build an Ethernet II / IPv4 frame around `bytes`, one fragment of a UDP datagram too long
/// for the link (RFC 791: identification `id`, its place `offset` in the IP payload, a
/// multiple of 8, and "more fragments"; the first fragment's bytes begin with the UDP
/// header), into `out` (cleared first).
pub fn build_fragment_frame(
    out: &mut Vec<u8>,
    ep: &UdpEndpoints,
    (id, offset, more): (u16, usize, bool),
    bytes: &[u8],
) -> io::Result<()> {
    out.clear();
    let eth = etherparse::Ethernet2Header {
        source: ep.src_mac,
        destination: ep.dst_mac,
        ether_type: EtherType::IPV4,
    };
    let len = u16::try_from(bytes.len()).map_err(io::Error::other)?;
    let mut ip =
        etherparse::Ipv4Header::new(len, 64, etherparse::IpNumber::UDP, ep.src_ip, ep.dst_ip)
            .map_err(io::Error::other)?;
    ip.identification = id;
    ip.dont_fragment = false;
    ip.more_fragments = more;
    let units = u16::try_from(offset / 8).map_err(io::Error::other)?;
    ip.fragment_offset = etherparse::IpFragOffset::try_new(units).map_err(io::Error::other)?;
    out.reserve(14 + 20 + bytes.len());
    eth.write(out)?;
    ip.write(out)?;
    out.extend_from_slice(bytes);
    Ok(())
}

/// Build an Ethernet II / IPv4 / UDP frame around `payload` into `out` (cleared first), with
/// correct lengths and IPv4 and UDP checksums. Fails only for a payload over 65507 bytes.
pub fn build_udp_frame(
    out: &mut Vec<u8>,
    ep: &UdpEndpoints,
    src_port: u16,
    dst_port: u16,
    payload: &[u8],
) -> io::Result<()> {
    out.clear();
    let b = etherparse::PacketBuilder::ethernet2(ep.src_mac, ep.dst_mac)
        .ipv4(ep.src_ip, ep.dst_ip, 64)
        .udp(src_port, dst_port);
    out.reserve(b.size(payload.len()));
    b.write(out, payload).map_err(io::Error::other)
}
