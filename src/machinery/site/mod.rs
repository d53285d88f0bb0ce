//! `rths site`: the experimental site an unmodified OpenSees drives through its `genericClient`
//! element (docs/site.md). Each element is its own connection (port PORT + i) and its own actuator
//! (the virtual rig, or the board over the link); the test of each runs in its own thread.

pub mod board;
pub mod element;
pub mod experiment;
pub mod protocol;
pub mod virtual_rig;

use std::io::Write;
use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::path::{Path, PathBuf};

use anyhow::Context;

use element::{ElementOutcome, ElementSetup};
use experiment::Experiment;

/// One element of `rths site`: what it knows of its rig, its actuator, and what its recording's
/// header says of them.
pub struct SiteElement {
    /// The identified stiffness and the pace.
    pub setup: ElementSetup,
    /// Its actuator: a virtual rig, or a board of its own.
    pub experiment: Box<dyn Experiment>,
    /// Header fields of this element's recording (its rig file, preset, link).
    pub header: Vec<(String, String)>,
}

/// What `rths site` serves.
pub struct SiteConfig {
    /// The first element's address (element i: port + i).
    pub listen: SocketAddr,
    /// UDP instead of TCP.
    pub udp: bool,
    /// One element per connection.
    pub elements: Vec<SiteElement>,
    /// Where the recording goes (element i > 0 of several: `STEM-i.EXT`, the first `STEM-1.EXT`).
    pub out: Option<PathBuf>,
    /// Header fields every recording gets (the pace).
    pub header: Vec<(String, String)>,
}

/// The recording path of element `i` of `k`.
pub fn recording_path(out: &Path, i: usize, k: usize) -> PathBuf {
    if k == 1 {
        return out.to_path_buf();
    }
    let stem = out
        .file_stem()
        .map_or_else(|| "run".into(), |s| s.to_string_lossy().into_owned());
    let name = match out.extension() {
        Some(e) => format!("{stem}-{}.{}", i + 1, e.to_string_lossy()),
        None => format!("{stem}-{}", i + 1),
    };
    out.with_file_name(name)
}

enum Bound {
    Tcp(TcpListener),
    Udp(UdpSocket),
}

/// Serve every element to its client's DIE; prints `listening on ADDRESS` per element when
/// ready. Returns each element's outcome (recordings written, whatever happened).
pub fn run(cfg: SiteConfig) -> anyhow::Result<Vec<ElementOutcome>> {
    let k = cfg.elements.len();
    let mut bound = Vec::with_capacity(k);
    for i in 0..k {
        let port = u16::try_from(usize::from(cfg.listen.port()) + i)
            .context("the element ports run past 65535")?;
        let addr = SocketAddr::new(cfg.listen.ip(), port);
        let (b, local) = if cfg.udp {
            let s = UdpSocket::bind(addr).with_context(|| format!("binding UDP {addr}"))?;
            let l = s.local_addr()?;
            (Bound::Udp(s), l)
        } else {
            let s = TcpListener::bind(addr).with_context(|| format!("binding TCP {addr}"))?;
            let l = s.local_addr()?;
            (Bound::Tcp(s), l)
        };
        crate::outln!("listening on {local}");
        bound.push((b, local));
    }
    std::io::stdout().flush()?;
    let mut element_headers = Vec::with_capacity(k);
    let handles: Vec<_> = bound
        .into_iter()
        .zip(cfg.elements)
        .enumerate()
        .map(|(i, ((b, local), e))| {
            element_headers.push(e.header);
            let (setup, mut exp) = (e.setup, e.experiment);
            std::thread::spawn(move || serve_element(i, b, local, &setup, exp.as_mut()))
        })
        .collect();
    let mut outcomes = Vec::with_capacity(k);
    let mut first_error = None;
    for (i, h) in handles.into_iter().enumerate() {
        let Ok((local, proto, r)) = h.join() else {
            first_error.get_or_insert(anyhow::anyhow!("element {} stopped unexpectedly", i + 1));
            continue;
        };
        // An element refused before its test began has no recording; the others are kept.
        let o = match r.with_context(|| format!("element {} ({local})", i + 1)) {
            Ok(o) => o,
            Err(e) => {
                first_error.get_or_insert(e);
                continue;
            }
        };
        if let Some(out) = &cfg.out {
            let path = recording_path(out, i, k);
            let mut hd = crate::link_host::RunHeader::default();
            hd.set("source", "site");
            hd.set("link", format!("opensees-{proto} {local}"));
            hd.set("element", i + 1);
            for (key, v) in cfg
                .header
                .iter()
                .chain(element_headers.get(i).into_iter().flatten())
            {
                hd.set(key, v);
            }
            hd.set("dofs", o.dofs);
            hd.set("ticks_per_step", o.ticks_per_step);
            hd.set("steps", o.steps);
            if let Some(r) = &o.stop_reason {
                hd.set("stop_reason", r);
            }
            element::write_recording(&path, &hd, &o.rows)
                .with_context(|| format!("writing {}", path.display()))?;
            crate::outln!("wrote {}", path.display());
        }
        outcomes.push(o);
    }
    match first_error {
        Some(e) => Err(e),
        None => Ok(outcomes),
    }
}

type Served = (SocketAddr, &'static str, anyhow::Result<ElementOutcome>);

fn serve_element(
    i: usize,
    b: Bound,
    local: SocketAddr,
    setup: &ElementSetup,
    exp: &mut dyn Experiment,
) -> Served {
    match b {
        Bound::Tcp(l) => {
            let r = (|| {
                let (stream, peer) = l.accept()?;
                eprintln!("site: element {} ({local}): client {peer}", i + 1);
                element::tune_tcp(&stream);
                stream.set_read_timeout(Some(element::SILENT_CLIENT))?;
                // One client per element: any other is refused while this test runs.
                if let Ok(l2) = l.try_clone() {
                    std::thread::spawn(move || {
                        for c in l2.incoming().flatten() {
                            let who = c.peer_addr().map(|a| a.to_string()).unwrap_or_default();
                            eprintln!(
                                "site: element {} ({local}): refused a second client {who}: a \
                                 test runs",
                                i + 1
                            );
                            drop(c);
                        }
                    });
                }
                element::serve(element::ElementChannel::Tcp(stream), setup, exp)
            })();
            (local, "tcp", r)
        }
        Bound::Udp(s) => {
            let r = (|| {
                let ch = element::udp_accept(s)?;
                if let element::ElementChannel::Udp(s, _) = &ch {
                    s.set_read_timeout(Some(element::SILENT_CLIENT))?;
                }
                element::serve(ch, setup, exp)
            })();
            (local, "udp", r)
        }
    }
}
