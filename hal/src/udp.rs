//! Live UDP input (the VLP-16 on Ethernet): one socket per port, set up with socket2 (address
//! reuse, a large receive buffer so bursts wait in the kernel, a read timeout so a reader
//! thread notices shutdown), read through std's safe `UdpSocket`.
//!
//! The receive time is the kernel's (SO_TIMESTAMPNS, socket(7): the time the datagram reached
//! the socket, read from the `recvmsg` control message) where the OS gives it, else the host's
//! wall clock right after the read returns. A socket is bound only once the kernel stamps
//! datagrams on arrival (Linux turns the stamps on some time after the first socket asks).
//! The kernel's own drop count for the socket (its receive buffer was full) is read from
//! /proc/net/udp.

use crate::packet::{Datagram, HostTime, PacketSource, Record};
use socket2::{Domain, Protocol, Socket, Type};
use std::io;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::time::Duration;

/// Receive buffer asked of the kernel (the VLP-16 sends ~1 MB/s; 8 MB holds 8 s).
pub const RECV_BUFFER: usize = 8 << 20;

/// Room for one SO_TIMESTAMPNS control message, aligned as `cmsghdr` needs.
#[repr(C, align(8))]
struct CmsgBuf([u8; 64]);

/// A bound UDP port.
pub struct UdpSource {
    socket: UdpSocket,
    port: u16,
    buf: Box<[u8; 65_536]>,
    cmsg: Box<CmsgBuf>,
    kernel_stamps: bool,
    /// Datagrams received.
    pub received: u64,
    /// Datagrams that carried a kernel receive time.
    pub kernel_stamped: u64,
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
        // Stamping is asked for, and known to be on, before the socket can queue a datagram.
        let kernel_stamps = enable_kernel_stamps(&s) && await_arrival_stamps();
        s.bind(&SocketAddr::V4(SocketAddrV4::new(addr, port)).into())?;
        let socket: UdpSocket = s.into();
        let port = socket.local_addr()?.port();
        Ok(Self {
            socket,
            port,
            buf: Box::new([0; 65_536]),
            cmsg: Box::new(CmsgBuf([0; 64])),
            kernel_stamps,
            received: 0,
            kernel_stamped: 0,
        })
    }

    /// Does the kernel stamp this socket's datagrams on their arrival?
    pub fn kernel_stamps(&self) -> bool {
        self.kernel_stamps
    }

    /// Datagrams the kernel dropped for this socket because its receive buffer was full
    /// (the `drops` column of /proc/net/udp for this socket's inode); `None` where the OS does
    /// not say.
    pub fn kernel_drops(&self) -> Option<u64> {
        kernel_drops(&self.socket)
    }

    /// A handle that reads this socket's kernel drop count from another thread (while the
    /// socket is open).
    pub fn drop_probe(&self) -> DropProbe {
        DropProbe(socket_inode(&self.socket))
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
        let got = if self.kernel_stamps {
            recv_stamped(&self.socket, &mut self.buf[..], &mut self.cmsg.0)
        } else {
            self.socket
                .recv_from(&mut self.buf[..])
                .map(|(n, a)| (n, a, None))
        };
        match got {
            Ok((n, from, stamp)) => {
                let time = HostTime(match stamp {
                    Some(t) => {
                        self.kernel_stamped += 1;
                        t
                    }
                    None => crate::clock::wall().0,
                });
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

/// A live socket as a packet source: a timed-out read is [`Record::Idle`]; it never ends.
impl PacketSource for UdpSource {
    type Error = io::Error;

    fn next_record(&mut self) -> io::Result<Option<Record<'_>>> {
        Ok(Some(match self.recv()? {
            Some(d) => Record::Udp(d),
            None => Record::Idle,
        }))
    }
}

/// Reads one socket's kernel drop count (the `drops` column of /proc/net/udp); `None` where
/// the OS does not say or the socket is closed.
#[derive(Debug, Clone)]
pub struct DropProbe(Option<String>);

impl DropProbe {
    /// The count now.
    pub fn read(&self) -> Option<u64> {
        let inode = self.0.as_deref()?;
        let table = std::fs::read_to_string("/proc/net/udp").ok()?;
        parse_proc_udp_drops(&table, inode)
    }
}

#[cfg(target_os = "linux")]
fn enable_kernel_stamps(s: &impl std::os::fd::AsFd) -> bool {
    nix::sys::socket::setsockopt(s, nix::sys::socket::sockopt::ReceiveTimestampns, &true).is_ok()
}

#[cfg(not(target_os = "linux"))]
fn enable_kernel_stamps<S>(_: &S) -> bool {
    false
}

/// Longest wait for the kernel to stamp datagrams on arrival.
const STAMP_WAIT: Duration = Duration::from_millis(500);

/// Waits until Linux stamps datagrams when they arrive; false if it did not within
/// [`STAMP_WAIT`] (or loopback is down).
///
/// The first socket to ask for receive stamps turns them on for the whole system by a deferred
/// work item (net/core/dev.c, `net_enable_timestamp`); a datagram that arrives before it has
/// run is stamped when it is read instead (net/core/sock.c, `__sock_recv_timestamp`), so a
/// burst read late would carry times later than the datagrams after it. A probe datagram on
/// loopback, read a little after it was sent, tells which: it carries its sending time once
/// stamping is on. The socket that asked keeps it on while it is open.
#[cfg(target_os = "linux")]
fn await_arrival_stamps() -> bool {
    let probe = || -> io::Result<bool> {
        let rx = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0))?;
        rx.set_read_timeout(Some(Duration::from_millis(100)))?;
        if !enable_kernel_stamps(&rx) {
            return Ok(false);
        }
        let tx = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0))?;
        let to = rx.local_addr()?;
        let start = std::time::Instant::now();
        let (mut buf, mut cmsg) = ([0u8; 8], CmsgBuf([0; 64]));
        while start.elapsed() < STAMP_WAIT {
            tx.send_to(b"probe", to)?;
            std::thread::sleep(Duration::from_millis(2));
            let read = crate::clock::wall().0;
            if let (_, _, Some(stamp)) = recv_stamped(&rx, &mut buf, &mut cmsg.0)? {
                if stamp < read {
                    return Ok(true);
                }
            }
        }
        Ok(false)
    };
    probe().unwrap_or(false)
}

#[cfg(not(target_os = "linux"))]
fn await_arrival_stamps() -> bool {
    false
}

/// `recvmsg` with the SO_TIMESTAMPNS control message: (bytes, sender, kernel time [ns]).
#[cfg(target_os = "linux")]
fn recv_stamped(
    s: &UdpSocket,
    buf: &mut [u8],
    cmsg: &mut [u8],
) -> io::Result<(usize, SocketAddr, Option<i64>)> {
    use nix::sys::socket::{recvmsg, ControlMessageOwned, MsgFlags, SockaddrIn};
    use std::os::fd::AsRawFd;
    let mut iov = [io::IoSliceMut::new(buf)];
    let msg = recvmsg::<SockaddrIn>(s.as_raw_fd(), &mut iov, Some(cmsg), MsgFlags::empty())
        .map_err(io::Error::from)?;
    let mut stamp = None;
    if let Ok(cmsgs) = msg.cmsgs() {
        for c in cmsgs {
            if let ControlMessageOwned::ScmTimestampns(ts) = c {
                stamp = Some(HostTime::from_secs_nanos(ts.tv_sec(), ts.tv_nsec() as u32).0);
            }
        }
    }
    let from = msg.address.map_or(
        SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, 0)),
        |a| SocketAddr::V4(SocketAddrV4::new(a.ip(), a.port())),
    );
    Ok((msg.bytes, from, stamp))
}

#[cfg(not(target_os = "linux"))]
fn recv_stamped(
    s: &UdpSocket,
    buf: &mut [u8],
    _: &mut [u8],
) -> io::Result<(usize, SocketAddr, Option<i64>)> {
    s.recv_from(buf).map(|(n, a)| (n, a, None))
}

fn kernel_drops(s: &UdpSocket) -> Option<u64> {
    DropProbe(socket_inode(s)).read()
}

/// The socket's inode, as /proc/net/udp names it.
#[cfg(target_os = "linux")]
fn socket_inode(s: &UdpSocket) -> Option<String> {
    use std::os::fd::AsRawFd;
    let link = std::fs::read_link(format!("/proc/self/fd/{}", s.as_raw_fd())).ok()?;
    Some(
        link.to_str()?
            .strip_prefix("socket:[")?
            .strip_suffix(']')?
            .to_string(),
    )
}

#[cfg(not(target_os = "linux"))]
fn socket_inode(_: &UdpSocket) -> Option<String> {
    None
}

/// The `drops` column of the /proc/net/udp row whose inode (column 10) is `inode`.
pub fn parse_proc_udp_drops(table: &str, inode: &str) -> Option<u64> {
    table.lines().skip(1).find_map(|l| {
        let cols: Vec<&str> = l.split_whitespace().collect();
        (cols.get(9) == Some(&inode))
            .then(|| cols.last()?.parse().ok())
            .flatten()
    })
}

/// Sockets bound to local UDP `port` in a /proc/net/udp table (column 2 `ADDR:PORT`, hex).
pub fn proc_udp_bound(table: &str, port: u16) -> usize {
    table
        .lines()
        .skip(1)
        .filter_map(|l| l.split_whitespace().nth(1))
        .filter_map(|a| a.rsplit_once(':'))
        .filter(|(_, p)| u16::from_str_radix(p, 16) == Ok(port))
        .count()
}

/// Sockets of any program bound to local UDP `port` now (Linux; `None` elsewhere).
pub fn bound_sockets(port: u16) -> Option<usize> {
    let table = std::fs::read_to_string("/proc/net/udp").ok()?;
    Some(proc_udp_bound(&table, port))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proc_net_udp_drops_column() {
        // A row as Linux 6.x prints it (header, then one socket).
        let t = "   sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout inode ref pointer drops\n\
                 \x20 1: 0100007F:0940 00000000:0000 07 00000000:00000000 00:00000000 00000000  1000        0 81234 2 0000000000000000 17\n";
        assert_eq!(parse_proc_udp_drops(t, "81234"), Some(17));
        assert_eq!(parse_proc_udp_drops(t, "1"), None);
        // 0x0940 = 2368.
        assert_eq!(proc_udp_bound(t, 2368), 1);
        assert_eq!(proc_udp_bound(t, 8308), 0);
    }

    /// A datagram sent to ourselves carries a kernel receive time close to the wall clock.
    #[cfg(target_os = "linux")]
    #[test]
    fn kernel_receive_time() {
        let mut rx = UdpSource::bind(Ipv4Addr::LOCALHOST, 0, Duration::from_millis(500)).unwrap();
        assert!(rx.kernel_stamps());
        let tx = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
        let before = crate::clock::wall().0;
        tx.send_to(b"hello", (Ipv4Addr::LOCALHOST, rx.port()))
            .unwrap();
        let d = rx.recv().unwrap().expect("a datagram");
        let after = crate::clock::wall().0;
        assert_eq!(d.payload, b"hello");
        assert!(
            d.time.0 >= before - 1_000_000 && d.time.0 <= after,
            "{:?}",
            d.time
        );
        assert_eq!(d.src_port, tx.local_addr().unwrap().port());
        assert_eq!(rx.kernel_stamped, 1);
        assert_eq!(rx.kernel_drops(), Some(0));
        assert_eq!(rx.drop_probe().read(), Some(0));
        // Nothing more within the timeout: the source is idle, not ended.
        assert!(matches!(rx.next_record(), Ok(Some(Record::Idle))));
        let probe = rx.drop_probe();
        drop(rx);
        assert_eq!(probe.read(), None, "a closed socket has no row");
    }

    /// A datagram that waits in the socket is stamped when it arrived, not when it is read,
    /// from the first one on. Without [`await_arrival_stamps`] this fails whenever the
    /// kernel's deferred switch has not run before the first datagram; force that with
    /// `chrt -f 50 taskset -c 0` on the test binary (the switch's worker then waits for the
    /// test to sleep).
    #[cfg(target_os = "linux")]
    #[test]
    fn the_first_datagram_carries_its_arrival_time() {
        let mut rx = UdpSource::bind(Ipv4Addr::LOCALHOST, 0, Duration::from_millis(500)).unwrap();
        let tx = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
        tx.send_to(b"first", (Ipv4Addr::LOCALHOST, rx.port()))
            .unwrap();
        let sent = crate::clock::wall().0;
        std::thread::sleep(Duration::from_millis(20));
        let read = crate::clock::wall().0;
        assert!(rx.kernel_stamps());
        let d = rx.recv().unwrap().expect("a datagram");
        assert!(
            d.time.0 <= sent,
            "stamped {:.3} ms after it was sent; the read was {:.3} ms after",
            (d.time.0 - sent) as f64 / 1e6,
            (read - sent) as f64 / 1e6
        );
    }
}
