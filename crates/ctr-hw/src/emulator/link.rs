//! The transport side of the emulator: an in-process link ([`EmulatedLink`]), a server
//! thread that answers on any [`Transport`] ([`EmulatorServer`]), and a pseudo-terminal
//! served by such a thread ([`PtyEmulator`]) that any serial program can open.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::Emulator;
use crate::protocol::Decoder;
use crate::transport::{Inbox, SerialTransport, Transport, TransportError};

/// How long the server thread waits for bytes before it checks whether to stop (and
/// advances the clock).
const SERVE_POLL: Duration = Duration::from_millis(10);
/// The most bytes the server thread takes from the transport at once.
const READ_CHUNK: usize = 512;

impl Emulator {
    /// An in-process [`Transport`] to this bus: writes are handled at once, replies are
    /// readable right after, and a read with nothing to read times out at once.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut bus = Bus::new(emu.link(), BusConfig::default());
    /// assert_eq!(bus.ping(4).unwrap().id, 4);
    /// ```
    pub fn link(&self) -> EmulatedLink {
        EmulatedLink {
            emulator: self.clone(),
            decoder: Decoder::new(),
            input: Inbox::default(),
        }
    }

    /// Serves this bus over `transport` from a new thread until stopped.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// use ctr_hw::transport::SerialTransport;
    /// let (master, _slave) = serialport::TTYPort::pair().unwrap();
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let server = emu.serve(SerialTransport::from_port(Box::new(master)));
    /// server.stop().unwrap();
    /// ```
    pub fn serve<T: Transport + Send + 'static>(&self, mut transport: T) -> EmulatorServer {
        let stop = Arc::new(AtomicBool::new(false));
        let emulator = self.clone();
        let stop_flag = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let mut decoder = Decoder::new();
            let mut buf = [0u8; READ_CHUNK];
            while !stop_flag.load(Ordering::Relaxed) {
                match transport.read(&mut buf, Instant::now() + SERVE_POLL) {
                    Ok(n) => {
                        let reply = emulator.process(&mut decoder, &buf[..n]);
                        if !reply.is_empty() {
                            transport.write_all(&reply)?;
                        }
                    }
                    Err(error) if transport.is_timeout(&error) => emulator.lock().sync_clock(),
                    Err(error) => return Err(error),
                }
            }
            Ok(())
        });
        EmulatorServer {
            stop,
            thread: Some(thread),
        }
    }

    /// Opens a pseudo-terminal pair and serves this bus on it; open
    /// [`PtyEmulator::path`] as a serial port to talk to it.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let pty = Emulator::new(EmulatorConfig::default()).serve_pty().unwrap();
    /// assert!(pty.path().starts_with("/dev/"));
    /// ```
    pub fn serve_pty(&self) -> Result<PtyEmulator, TransportError> {
        let (master, peer) = serialport::TTYPort::pair()?;
        let path = serialport::SerialPort::name(&peer).ok_or_else(|| TransportError::Io {
            kind: std::io::ErrorKind::NotFound,
            message: "pseudo-terminal has no path".into(),
        })?;
        let server = self.serve(SerialTransport::from_port(Box::new(master)));
        Ok(PtyEmulator {
            server,
            peer,
            path,
            emulator: self.clone(),
        })
    }
}

/// The in-process [`Transport`] returned by [`Emulator::link`].
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// use ctr_hw::transport::Transport;
/// use ctr_hw::protocol::Packet;
/// let mut link = Emulator::new(EmulatorConfig::default()).link();
/// link.write_all(&Packet::ping(1).encode().unwrap()).unwrap();
/// let mut buf = [0u8; 64];
/// assert_eq!(link.read(&mut buf, std::time::Instant::now()).unwrap(), 14);
/// ```
#[derive(Debug)]
pub struct EmulatedLink {
    emulator: Emulator,
    decoder: Decoder,
    input: Inbox,
}

impl EmulatedLink {
    /// The emulator behind this link.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let link = Emulator::new(EmulatorConfig::default()).link();
    /// assert_eq!(link.emulator().ids().len(), 4);
    /// ```
    pub fn emulator(&self) -> &Emulator {
        &self.emulator
    }
}

impl Transport for EmulatedLink {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        let reply = self.emulator.process(&mut self.decoder, bytes);
        self.input.push(reply);
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _deadline: Instant) -> Result<usize, TransportError> {
        self.input.read(buf, 0)
    }

    fn discard_input(&mut self) -> Result<(), TransportError> {
        self.input.clear();
        Ok(())
    }
}

/// A running emulator thread (see [`Emulator::serve`]); dropping it stops the thread.
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// let emu = Emulator::new(EmulatorConfig::default());
/// let server = emu.serve(emu.link()); // serving a link is pointless but harmless
/// assert!(!server.is_finished());
/// server.stop().unwrap();
/// ```
#[derive(Debug)]
pub struct EmulatorServer {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), TransportError>>>,
}

impl EmulatorServer {
    /// Stops the thread and returns how it ended.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// assert!(emu.serve(emu.link()).stop().is_ok());
    /// ```
    pub fn stop(mut self) -> Result<(), TransportError> {
        self.stop.store(true, Ordering::Relaxed);
        self.join()
    }

    /// Blocks until the thread ends by itself (a transport failure); serves forever
    /// otherwise.
    ///
    /// ```no_run
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// emu.serve(emu.link()).wait().unwrap();
    /// ```
    pub fn wait(mut self) -> Result<(), TransportError> {
        self.join()
    }

    /// Whether the thread has ended.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let server = emu.serve(emu.link());
    /// assert!(!server.is_finished());
    /// ```
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    fn join(&mut self) -> Result<(), TransportError> {
        match self.thread.take() {
            None => Ok(()),
            Some(thread) => thread.join().unwrap_or_else(|_| {
                Err(TransportError::Io {
                    kind: std::io::ErrorKind::Other,
                    message: "emulator thread panicked".into(),
                })
            }),
        }
    }
}

impl Drop for EmulatorServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        let _ = self.join();
    }
}

/// An emulator serving the master side of a pseudo-terminal (see
/// [`Emulator::serve_pty`]). It keeps its own handle on the slave side open, so that the
/// line does not hang up while clients come and go.
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// let pty = Emulator::new(EmulatorConfig::default()).serve_pty().unwrap();
/// let path = pty.path().to_owned();
/// assert_eq!(pty.emulator().ids(), [1, 2, 3, 4]);
/// pty.stop().unwrap();
/// ```
#[derive(Debug)]
pub struct PtyEmulator {
    // Field order matters: the server thread stops before the slave side closes.
    server: EmulatorServer,
    peer: serialport::TTYPort,
    path: String,
    emulator: Emulator,
}

impl PtyEmulator {
    /// The slave device path to open as a serial port (e.g. `/dev/pts/3`).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let pty = Emulator::new(EmulatorConfig::default()).serve_pty().unwrap();
    /// assert!(std::path::Path::new(pty.path()).exists());
    /// ```
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The emulated bus (for fault injection and inspection).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault};
    /// let pty = Emulator::new(EmulatorConfig::default()).serve_pty().unwrap();
    /// pty.emulator().inject(None, Fault::NoReply);
    /// ```
    pub fn emulator(&self) -> &Emulator {
        &self.emulator
    }

    /// Stops serving and closes the pseudo-terminal.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// Emulator::new(EmulatorConfig::default()).serve_pty().unwrap().stop().unwrap();
    /// ```
    pub fn stop(self) -> Result<(), TransportError> {
        let Self { server, peer, .. } = self;
        let result = server.stop();
        drop(peer);
        result
    }

    /// Serves until the thread fails (normally: until the process ends).
    ///
    /// ```no_run
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let pty = Emulator::new(EmulatorConfig::default()).serve_pty()?;
    /// println!("{}", pty.path());
    /// pty.wait()?;
    /// # Ok::<(), ctr_hw::transport::TransportError>(())
    /// ```
    pub fn wait(self) -> Result<(), TransportError> {
        let Self { server, peer, .. } = self;
        let result = server.wait();
        drop(peer);
        result
    }
}
