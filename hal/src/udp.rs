//! Live UDP input (the VLP-16 on Ethernet): one socket per port, set up with socket2 (address
//! reuse, a large receive buffer so bursts wait in the kernel, a read timeout so a reader
//! thread notices shutdown), read through std's safe `UdpSocket`.
//!
//! The receive time is taken on the host's wall clock right after the read returns (kernel
//! SO_TIMESTAMPNS control messages are not read yet: see NOTES.md, issue #7).

use crate::packet::{Datagram, HostTime};
use socket2::{Domain, Protocol, Socket, Type};
use std::io;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::time::Duration;

/// Receive buffer asked of the kernel (the VLP-16 sends ~1 MB/s; 8 MB holds 8 s).
pub const RECV_BUFFER: usize = 8 << 20;

/// A bound UDP port.
pub struct UdpSource {
    socket: UdpSocket,
    port: u16,
    buf: Box<[u8; 65_536]>,
    /// Datagrams received.
    pub received: u64,
}

impl UdpSource {
    /// Bind `addr:port` (port 0: any free port) with address reuse, the big receive buffer and
    /// a read timeout.
    pub fn bind(addr: Ipv4Addr, port: u16, timeout: Duration) -> io::Result<Self> {
        let s = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
        s.set_reuse_address(true)?;
        // The kernel may cap the size (net.core.rmem_max): a smaller buffer is not fatal.
        let _ = s.set_recv_buffer_size(RECV_BUFFER);
        s.set_read_timeout(Some(timeout.max(Duration::from_millis(1))))?;
        s.bind(&SocketAddr::V4(SocketAddrV4::new(addr, port)).into())?;
        let socket: UdpSocket = s.into();
        let port = socket.local_addr()?.port();
        Ok(Self {
            socket,
            port,
            buf: Box::new([0; 65_536]),
            received: 0,
        })
    }

    /// The port actually bound.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// The kernel's receive buffer size.
    pub fn recv_buffer(&self) -> io::Result<usize> {
        Socket::from(self.socket.try_clone()?).recv_buffer_size()
    }

    /// The next datagram, or `None` if the read timed out.
    pub fn recv(&mut self) -> io::Result<Option<Datagram<'_>>> {
        match self.socket.recv_from(&mut self.buf[..]) {
            Ok((n, from)) => {
                let time = HostTime(i128::from(crate::serial::wall_ns()));
                self.received += 1;
                let (src_addr, src_port) = match from {
                    SocketAddr::V4(a) => (*a.ip(), a.port()),
                    SocketAddr::V6(a) => (
                        a.ip().to_ipv4_mapped().unwrap_or(Ipv4Addr::UNSPECIFIED),
                        a.port(),
                    ),
                };
                Ok(Some(Datagram {
                    time,
                    src_addr,
                    src_port,
                    dst_port: self.port,
                    payload: &self.buf[..n],
                    offset: 0,
                }))
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock
                        | io::ErrorKind::TimedOut
                        | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }
}
