//! A QEMU process of our own running the link firmware, its link port on a loopback socket.

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use super::error::LinkHostError;
use super::session::Link;

/// The emulated board an ELF was built for: the Cortex-M7 (`mps2-an500`) if its ARM attributes
/// name that CPU (`cargo build-m7`: `-C target-cpu=cortex-m7`), else the Cortex-M4
/// (`netduinoplus2`).
fn is_cortex_m7(elf: &Path) -> bool {
    std::fs::read(elf)
        .ok()
        .and_then(|b| arm_attributes(&b).map(|a| a.windows(10).any(|w| w == b"cortex-m7\0")))
        .unwrap_or(false)
}

/// The `.ARM.attributes` section of a 32-bit little-endian ELF, if it has one.
fn arm_attributes(b: &[u8]) -> Option<&[u8]> {
    let u16_at = |o: usize| Some(u16::from_le_bytes(b.get(o..o + 2)?.try_into().ok()?) as usize);
    let u32_at = |o: usize| Some(u32::from_le_bytes(b.get(o..o + 4)?.try_into().ok()?) as usize);
    if b.get(..5)? != b"\x7fELF\x01" {
        return None;
    }
    let (shoff, shentsize, shnum, shstrndx) = (u32_at(32)?, u16_at(46)?, u16_at(48)?, u16_at(50)?);
    let section = |i: usize| {
        let h = shoff + i * shentsize;
        Some((u32_at(h)?, u32_at(h + 16)?, u32_at(h + 20)?))
    };
    let (_, names_at, _) = section(shstrndx)?;
    (0..shnum).find_map(|i| {
        let (name, off, size) = section(i)?;
        let n = b.get(names_at + name..)?;
        let end = n.iter().position(|c| *c == 0)?;
        (n.get(..end)? == b".ARM.attributes").then(|| b.get(off..off + size))?
    })
}

/// The QEMU command line of the emulated board with its link port (USART2, QEMU's second serial
/// port) connected, as a client, to `127.0.0.1:port` (the runner of `firmware/.cargo/config.toml`
/// with `-serial tcp:` after its `-serial null`): the Cortex-M4 (`netduinoplus2`, `-icount
/// shift=0`), or for an ELF built for the Cortex-M7 the `run-m7` alias's (`mps2-an500`, `-icount
/// shift=3`).
pub fn qemu_args(elf: &Path, port: u16) -> Vec<String> {
    // nodelay: the board's small frames (a site's step end) must not wait on Nagle.
    let serial = format!("tcp:127.0.0.1:{port},nodelay=on");
    let (cpu, machine, icount) = if is_cortex_m7(elf) {
        ("cortex-m7", "mps2-an500", "shift=3,align=off,sleep=off")
    } else {
        ("cortex-m4", "netduinoplus2", "shift=0,align=off,sleep=off")
    };
    [
        "-cpu",
        cpu,
        "-machine",
        machine,
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
        icount,
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
