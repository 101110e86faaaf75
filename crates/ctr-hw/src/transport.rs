//! The byte link under the bus: a [`Transport`] trait, a serial-port implementation and a
//! scripted mock for tests.
//!
//! A transport moves bytes and nothing else: it knows no packets. Reads take a deadline
//! and either return at least one byte or fail with [`TransportError::Timeout`], which is
//! how the bus tells "no reply" apart from a broken link.
//!
//! ```
//! use ctr_hw::transport::{MockTransport, Transport};
//! use std::time::{Duration, Instant};
//!
//! let mut link = MockTransport::new();
//! link.push_reply(vec![1, 2, 3]);
//! link.write_all(&[0xAA]).unwrap();
//! let mut buf = [0u8; 8];
//! let n = link.read(&mut buf, Instant::now() + Duration::from_millis(10)).unwrap();
//! assert_eq!(&buf[..n], &[1, 2, 3]);
//! let err = link.read(&mut buf, Instant::now()).unwrap_err();
//! assert!(link.is_timeout(&err));
//! ```

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

/// Why a transport operation failed.
///
/// ```
/// use ctr_hw::transport::TransportError;
/// assert!(TransportError::Timeout.is_timeout());
/// assert!(!TransportError::Closed.is_timeout());
/// ```
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TransportError {
    /// The deadline passed before any byte arrived.
    #[error("timed out waiting for bytes")]
    Timeout,
    /// The other end hung up.
    #[error("the link is closed")]
    Closed,
    /// The serial port could not be opened or configured.
    #[error("serial port {path}: {message}")]
    Open {
        /// The port path.
        path: String,
        /// What the driver said.
        message: String,
    },
    /// Any other I/O failure.
    #[error("I/O error ({kind:?}): {message}")]
    Io {
        /// The I/O error kind.
        kind: io::ErrorKind,
        /// What the driver said.
        message: String,
    },
}

impl TransportError {
    /// Whether this is the deadline passing without data.
    ///
    /// ```
    /// assert!(ctr_hw::transport::TransportError::Timeout.is_timeout());
    /// ```
    pub fn is_timeout(&self) -> bool {
        matches!(self, Self::Timeout)
    }
}

impl From<io::Error> for TransportError {
    fn from(error: io::Error) -> Self {
        match error.kind() {
            io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock => Self::Timeout,
            io::ErrorKind::BrokenPipe | io::ErrorKind::UnexpectedEof => Self::Closed,
            kind => Self::Io {
                kind,
                message: error.to_string(),
            },
        }
    }
}

impl From<serialport::Error> for TransportError {
    fn from(error: serialport::Error) -> Self {
        Self::from(io::Error::from(error))
    }
}

/// A half-duplex byte link.
///
/// Implementations configure the line themselves (8 data bits, no parity, 1 stop bit, no
/// flow control for Dynamixel).
///
/// ```
/// use ctr_hw::transport::{Transport, TransportError};
/// use std::time::Instant;
///
/// /// A link where nothing ever answers.
/// struct Void;
/// impl Transport for Void {
///     fn write_all(&mut self, _: &[u8]) -> Result<(), TransportError> { Ok(()) }
///     fn read(&mut self, _: &mut [u8], _: Instant) -> Result<usize, TransportError> {
///         Err(TransportError::Timeout)
///     }
///     fn discard_input(&mut self) -> Result<(), TransportError> { Ok(()) }
/// }
/// let mut v = Void;
/// let err = v.read(&mut [0; 4], Instant::now()).unwrap_err();
/// assert!(v.is_timeout(&err));
/// ```
pub trait Transport {
    /// Writes every byte and returns once they are handed to the line.
    ///
    /// ```
    /// use ctr_hw::transport::{MockTransport, Transport};
    /// let mut m = MockTransport::new();
    /// m.write_all(&[1, 2]).unwrap();
    /// assert_eq!(m.written(), [vec![1, 2]]);
    /// ```
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError>;

    /// Reads at least one byte into `buf`, waiting until `deadline` at most; past it,
    /// fails with [`TransportError::Timeout`]. Never returns `Ok(0)` for a non-empty
    /// `buf`.
    ///
    /// ```
    /// use ctr_hw::transport::{MockTransport, Transport};
    /// use std::time::Instant;
    /// let mut m = MockTransport::new();
    /// assert!(m.read(&mut [0; 4], Instant::now()).unwrap_err().is_timeout());
    /// ```
    fn read(&mut self, buf: &mut [u8], deadline: Instant) -> Result<usize, TransportError>;

    /// Drops whatever has been received and not read yet (stale replies, line noise).
    ///
    /// ```
    /// use ctr_hw::transport::{MockTransport, Transport};
    /// use std::time::Instant;
    /// let mut m = MockTransport::new();
    /// m.push_input(&[9, 9]);
    /// m.discard_input().unwrap();
    /// assert!(m.read(&mut [0; 4], Instant::now()).is_err());
    /// ```
    fn discard_input(&mut self) -> Result<(), TransportError>;

    /// Whether `error` means "no data before the deadline" rather than a broken link.
    ///
    /// ```
    /// use ctr_hw::transport::{MockTransport, Transport, TransportError};
    /// let m = MockTransport::new();
    /// assert!(m.is_timeout(&TransportError::Timeout));
    /// assert!(!m.is_timeout(&TransportError::Closed));
    /// ```
    fn is_timeout(&self, error: &TransportError) -> bool {
        error.is_timeout()
    }
}

/// Implements [`Transport`] for pointers to a transport (`&mut T`, `Box<T>`) by
/// forwarding every method to the transport pointed to.
macro_rules! forward_transport {
    ($($pointer:ty),+) => {$(
        impl<T: Transport + ?Sized> Transport for $pointer {
            fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
                (**self).write_all(bytes)
            }
            fn read(&mut self, buf: &mut [u8], deadline: Instant) -> Result<usize, TransportError> {
                (**self).read(buf, deadline)
            }
            fn discard_input(&mut self) -> Result<(), TransportError> {
                (**self).discard_input()
            }
            fn is_timeout(&self, error: &TransportError) -> bool {
                (**self).is_timeout(error)
            }
        }
    )+};
}

forward_transport!(&mut T, Box<T>);

/// The port's read timeout until the first read sets its own from its deadline.
const INITIAL_READ_TIMEOUT: Duration = Duration::from_millis(100);

/// How long a write may take to hand its bytes to the line.
const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// A [`Transport`] over a `serialport` port (a USB adapter such as the U2D2, or a
/// pseudo-terminal in tests).
///
/// ```no_run
/// use ctr_hw::transport::SerialTransport;
/// let link = SerialTransport::open("/dev/ttyUSB0", 57_600)?;
/// # Ok::<(), ctr_hw::transport::TransportError>(())
/// ```
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
    write_timeout: Duration,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport")
            .field("port", &self.port.name())
            .field("write_timeout", &self.write_timeout)
            .finish()
    }
}

impl SerialTransport {
    /// Opens `path` at `baud` with 8N1 and no flow control.
    ///
    /// ```
    /// use ctr_hw::transport::{SerialTransport, TransportError};
    /// let err = SerialTransport::open("/nonexistent/tty", 57_600).unwrap_err();
    /// assert!(matches!(err, TransportError::Open { .. }));
    /// ```
    pub fn open(path: &str, baud: u32) -> Result<Self, TransportError> {
        let port = serialport::new(path, baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(INITIAL_READ_TIMEOUT)
            .open()
            .map_err(|e| TransportError::Open {
                path: path.to_owned(),
                message: e.to_string(),
            })?;
        Ok(Self::from_port(port))
    }

    /// Wraps a port that is already open and configured.
    ///
    /// ```
    /// use ctr_hw::transport::SerialTransport;
    /// let (master, _slave) = serialport::TTYPort::pair().unwrap();
    /// let link = SerialTransport::from_port(Box::new(master));
    /// ```
    pub fn from_port(port: Box<dyn serialport::SerialPort>) -> Self {
        Self {
            port,
            write_timeout: WRITE_TIMEOUT,
        }
    }

    /// The port's name (its path), if it has one.
    ///
    /// ```
    /// use ctr_hw::transport::SerialTransport;
    /// let (_master, slave) = serialport::TTYPort::pair().unwrap();
    /// let link = SerialTransport::from_port(Box::new(slave));
    /// assert!(link.name().unwrap().starts_with("/dev/"));
    /// ```
    pub fn name(&self) -> Option<String> {
        self.port.name()
    }
}

impl Transport for SerialTransport {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.port.set_timeout(self.write_timeout)?;
        self.port.write_all(bytes)?;
        // Wait until the bytes are on the wire, so the response deadline that follows
        // does not include the transmission of the request.
        self.port.flush()?;
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], deadline: Instant) -> Result<usize, TransportError> {
        if buf.is_empty() {
            return Ok(0);
        }
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Err(TransportError::Timeout);
            }
            self.port.set_timeout(deadline - now)?;
            match self.port.read(buf) {
                Ok(0) => return Err(TransportError::Closed),
                Ok(n) => return Ok(n),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e.into()),
            }
        }
    }

    fn discard_input(&mut self) -> Result<(), TransportError> {
        self.port.clear(serialport::ClearBuffer::Input)?;
        Ok(())
    }
}

/// Bytes that have arrived and wait to be read, handed out at once: the input side of
/// the in-process transports ([`MockTransport`] and the emulator's link), where nothing
/// is ever on its way, so an empty inbox is a timeout without waiting.
#[derive(Debug, Clone, Default)]
pub(crate) struct Inbox {
    bytes: VecDeque<u8>,
}

impl Inbox {
    /// Bytes arrive.
    pub(crate) fn push(&mut self, bytes: impl IntoIterator<Item = u8>) {
        self.bytes.extend(bytes);
    }

    /// Drops every byte not read yet.
    pub(crate) fn clear(&mut self) {
        self.bytes.clear();
    }

    /// Moves the oldest bytes into `buf`, at most `limit` of them (0: as many as fit);
    /// [`TransportError::Timeout`] when there are none.
    pub(crate) fn read(&mut self, buf: &mut [u8], limit: usize) -> Result<usize, TransportError> {
        if buf.is_empty() {
            return Ok(0);
        }
        if self.bytes.is_empty() {
            return Err(TransportError::Timeout);
        }
        let mut n = buf.len().min(self.bytes.len());
        if limit > 0 {
            n = n.min(limit);
        }
        for (slot, byte) in buf.iter_mut().zip(self.bytes.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }
}

/// One scripted answer of a [`MockTransport`] to a write.
///
/// ```
/// use ctr_hw::transport::MockReply;
/// let r = MockReply::Bytes(vec![0xFF]);
/// assert_ne!(r, MockReply::Silence);
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MockReply {
    /// These bytes become readable after the write.
    Bytes(Vec<u8>),
    /// Nothing comes back: reads time out.
    Silence,
}

/// A scripted [`Transport`] for tests: each write consumes the next [`MockReply`], every
/// write is recorded, and reads of an empty input fail with an immediate
/// [`TransportError::Timeout`] (simulated, no waiting).
///
/// ```
/// use ctr_hw::transport::{MockTransport, Transport};
/// use std::time::Instant;
///
/// let mut link = MockTransport::new().with_chunk_size(2);
/// link.push_reply(vec![1, 2, 3]);
/// link.push_silence();
/// link.write_all(b"first").unwrap();
/// let mut buf = [0u8; 8];
/// assert_eq!(link.read(&mut buf, Instant::now()).unwrap(), 2); // partial read
/// assert_eq!(link.read(&mut buf, Instant::now()).unwrap(), 1);
/// link.write_all(b"second").unwrap();
/// assert!(link.read(&mut buf, Instant::now()).unwrap_err().is_timeout());
/// assert_eq!(link.written().len(), 2);
/// ```
#[derive(Debug, Clone, Default)]
pub struct MockTransport {
    script: VecDeque<MockReply>,
    written: Vec<Vec<u8>>,
    input: Inbox,
    chunk_size: usize,
    discards: usize,
    timeouts: usize,
}

impl MockTransport {
    /// A mock with an empty script: every write gets silence.
    ///
    /// ```
    /// let m = ctr_hw::transport::MockTransport::new();
    /// assert_eq!(m.remaining_replies(), 0);
    /// ```
    pub fn new() -> Self {
        Self::default()
    }

    /// Hands out at most `n` bytes per read (0: everything available), to exercise
    /// partial reads.
    ///
    /// ```
    /// let m = ctr_hw::transport::MockTransport::new().with_chunk_size(1);
    /// ```
    pub fn with_chunk_size(mut self, n: usize) -> Self {
        self.chunk_size = n;
        self
    }

    /// Scripts the answer to the next unanswered write.
    ///
    /// ```
    /// let mut m = ctr_hw::transport::MockTransport::new();
    /// m.push_reply(vec![0xFF, 0xFF, 0xFD, 0x00]);
    /// assert_eq!(m.remaining_replies(), 1);
    /// ```
    pub fn push_reply(&mut self, bytes: Vec<u8>) -> &mut Self {
        self.script.push_back(MockReply::Bytes(bytes));
        self
    }

    /// Scripts silence (a timeout) as the answer to the next unanswered write.
    ///
    /// ```
    /// let mut m = ctr_hw::transport::MockTransport::new();
    /// m.push_silence().push_silence();
    /// assert_eq!(m.remaining_replies(), 2);
    /// ```
    pub fn push_silence(&mut self) -> &mut Self {
        self.script.push_back(MockReply::Silence);
        self
    }

    /// Puts bytes in the input right away, as if they were already on the line (stale
    /// data, noise).
    ///
    /// ```
    /// use ctr_hw::transport::{MockTransport, Transport};
    /// let mut m = MockTransport::new();
    /// m.push_input(&[7]);
    /// let mut buf = [0u8; 1];
    /// assert_eq!(m.read(&mut buf, std::time::Instant::now()).unwrap(), 1);
    /// ```
    pub fn push_input(&mut self, bytes: &[u8]) -> &mut Self {
        self.input.push(bytes.iter().copied());
        self
    }

    /// Every write so far, one entry per call.
    ///
    /// ```
    /// let m = ctr_hw::transport::MockTransport::new();
    /// assert!(m.written().is_empty());
    /// ```
    pub fn written(&self) -> &[Vec<u8>] {
        &self.written
    }

    /// Scripted replies not consumed yet.
    ///
    /// ```
    /// assert_eq!(ctr_hw::transport::MockTransport::new().remaining_replies(), 0);
    /// ```
    pub fn remaining_replies(&self) -> usize {
        self.script.len()
    }

    /// How often [`Transport::discard_input`] was called.
    ///
    /// ```
    /// use ctr_hw::transport::{MockTransport, Transport};
    /// let mut m = MockTransport::new();
    /// m.discard_input().unwrap();
    /// assert_eq!(m.discards(), 1);
    /// ```
    pub fn discards(&self) -> usize {
        self.discards
    }

    /// How many reads timed out.
    ///
    /// ```
    /// use ctr_hw::transport::{MockTransport, Transport};
    /// let mut m = MockTransport::new();
    /// let _ = m.read(&mut [0; 1], std::time::Instant::now());
    /// assert_eq!(m.timeouts(), 1);
    /// ```
    pub fn timeouts(&self) -> usize {
        self.timeouts
    }
}

impl Transport for MockTransport {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.written.push(bytes.to_vec());
        if let Some(MockReply::Bytes(reply)) = self.script.pop_front() {
            self.input.push(reply);
        }
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _deadline: Instant) -> Result<usize, TransportError> {
        let result = self.input.read(buf, self.chunk_size);
        if matches!(result, Err(TransportError::Timeout)) {
            self.timeouts += 1;
        }
        result
    }

    fn discard_input(&mut self) -> Result<(), TransportError> {
        self.discards += 1;
        self.input.clear();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn io_errors_map_to_timeouts_and_closures() {
        let timeout: TransportError = io::Error::from(io::ErrorKind::TimedOut).into();
        assert!(timeout.is_timeout());
        let closed: TransportError = io::Error::from(io::ErrorKind::BrokenPipe).into();
        assert_eq!(closed, TransportError::Closed);
        let other: TransportError = io::Error::other("boom").into();
        assert!(matches!(other, TransportError::Io { .. }));
    }

    #[test]
    fn mock_answers_in_script_order() {
        let mut m = MockTransport::new();
        m.push_silence().push_reply(vec![5]);
        m.write_all(&[1]).unwrap();
        let mut buf = [0u8; 4];
        assert!(m.read(&mut buf, Instant::now()).is_err());
        m.write_all(&[2]).unwrap();
        assert_eq!(m.read(&mut buf, Instant::now()).unwrap(), 1);
        assert_eq!(buf[0], 5);
        // Past the script: silence.
        m.write_all(&[3]).unwrap();
        assert!(m.read(&mut buf, Instant::now()).is_err());
        assert_eq!(m.written(), [vec![1], vec![2], vec![3]]);
        assert_eq!(m.timeouts(), 2);
    }

    #[test]
    fn serial_transport_over_a_pty_pair() {
        let (master, slave) = serialport::TTYPort::pair().unwrap();
        let mut a = SerialTransport::from_port(Box::new(master));
        let mut b = SerialTransport::from_port(Box::new(slave));
        a.write_all(&[1, 2, 3]).unwrap();
        let mut got = Vec::new();
        let deadline = Instant::now() + Duration::from_secs(2);
        let mut buf = [0u8; 8];
        while got.len() < 3 {
            let n = b.read(&mut buf, deadline).unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, [1, 2, 3]);
        let start = Instant::now();
        let err = b
            .read(&mut buf, Instant::now() + Duration::from_millis(20))
            .unwrap_err();
        assert!(b.is_timeout(&err));
        assert!(start.elapsed() >= Duration::from_millis(15));
        // Past the deadline: immediate timeout.
        assert!(b.read(&mut buf, start).unwrap_err().is_timeout());
    }
}
