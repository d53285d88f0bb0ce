//! The byte streams a link runs over: a TCP socket (QEMU's serial port on 127.0.0.1) or a serial
//! device.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use super::error::LinkHostError;

/// A byte stream both ways.
pub trait Port: Read + Write + Send {
    /// How long a read may block.
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()>;
}

impl Port for TcpStream {
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()> {
        self.set_read_timeout(Some(t))
    }
}

/// A serial port (`serialport`, built without libudev).
struct Serial(Box<dyn serialport::SerialPort>);

impl Read for Serial {
    fn read(&mut self, b: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(b)
    }
}

impl Write for Serial {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.write(b)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

impl Port for Serial {
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()> {
        self.0.set_timeout(t).map_err(std::io::Error::other)
    }
}

/// A TCP connection (QEMU `-serial tcp:127.0.0.1:PORT,server=on`), without Nagle's delay.
pub fn tcp(addr: &str) -> Result<Box<dyn Port>, LinkHostError> {
    let s = TcpStream::connect(addr)?;
    s.set_nodelay(true)?;
    Ok(Box::new(s))
}

/// A serial device at `baud`, 8N1, raw.
pub fn serial(path: &str, baud: u32) -> Result<Box<dyn Port>, LinkHostError> {
    let p = serialport::new(path, baud)
        .timeout(Duration::from_millis(100))
        .open()
        .map_err(|e| LinkHostError::Serial {
            path: path.to_string(),
            message: e.to_string(),
        })?;
    Ok(Box::new(Serial(p)))
}
