//! A QEMU process of our own running the link firmware, its link port on a loopback socket.

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use super::error::LinkHostError;
use super::session::Link;

/// The QEMU command line of the emulated board with its link port (USART2, QEMU's second serial
/// port) connected, as a client, to `127.0.0.1:port` (the runner of `firmware/.cargo/config.toml`
/// with `-serial tcp:` after its `-serial null`).
pub fn qemu_args(elf: &Path, port: u16) -> Vec<String> {
    // nodelay: the board's small frames (a site's step end) must not wait on Nagle.
    let serial = format!("tcp:127.0.0.1:{port},nodelay=on");
    [
        "-cpu",
        "cortex-m4",
        "-machine",
        "netduinoplus2",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "null",
        "-serial",
        &serial,
        "-semihosting-config",
        "enable=on,target=native",
        "-icount",
        "shift=0,align=off,sleep=off",
        "-kernel",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain([elf.display().to_string()])
    .collect()
}

/// A QEMU of our own running the link firmware, its serial port on a loopback socket.
pub struct Qemu {
    child: Child,
    /// The link to it.
    pub link: Link,
    /// Where QEMU's stdout (the semihosting RESULT line) goes.
    pub stdout_path: PathBuf,
}

impl Qemu {
    /// Start `qemu-system-arm` on `elf` (built with `--features link`), run in `dir` (its defmt.bin
    /// and stdout file go there), and accept its serial connection.
    pub fn start(elf: &Path, dir: &Path) -> Result<Self, LinkHostError> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        let port = listener.local_addr()?.port();
        let stdout_path = dir.join("qemu-stdout.txt");
        let out = std::fs::File::create(&stdout_path)?;
        let mut child = Command::new("qemu-system-arm")
            .args(qemu_args(elf, port))
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| LinkHostError::Qemu(format!("cannot start qemu-system-arm: {e}")))?;
        listener.set_nonblocking(true)?;
        let start = Instant::now();
        let stream = loop {
            match listener.accept() {
                Ok((s, _)) => break s,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    if let Some(st) = child.try_wait()? {
                        return Err(LinkHostError::Qemu(format!("exited early: {st}")));
                    }
                    if start.elapsed() > Duration::from_secs(20) {
                        let _ = child.kill();
                        let _ = child.wait();
                        return Err(LinkHostError::Qemu("did not connect within 20 s".into()));
                    }
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) => return Err(e.into()),
            }
        };
        stream.set_nonblocking(false)?;
        stream.set_nodelay(true)?;
        let mut q = Self {
            child,
            link: Link::new(Box::new(stream)),
            stdout_path,
        };
        q.link.wait_ready(Duration::from_secs(20))?;
        Ok(q)
    }

    /// What QEMU printed so far (semihosting: the CALIB and RESULT lines).
    pub fn stdout(&self) -> String {
        std::fs::read_to_string(&self.stdout_path).unwrap_or_default()
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
