//! The host's side of a streamed record's flow control: which chunks to send now, from what the
//! device last said (the next chunk it expects and the samples it can take), and what to send again
//! after a loss. No I/O here: [`super::session`] sends what this decides.
//!
//! The device answers every chunk with the chunk number it expects next and its free room after
//! that chunk; the chunks sent after the answered one are still in flight, so the room left for new
//! ones is that free room less the samples of the chunks in flight (conservative: a chunk in flight
//! that the device refuses only makes it smaller). The host never sends more than that room, so the
//! device never has to refuse a chunk for room. A chunk lost on the wire makes the next one arrive
//! out of order: the device refuses it and says which it expects; the host goes back to that one.

use rths_link::{HostMsg, StreamStatus};

/// A streamed record's chunks and where their sending stands.
#[derive(Debug, Clone)]
pub struct StreamFeed {
    chunks: Vec<HostMsg>,
    /// `before[j]`: samples in chunks `0..j`.
    before: Vec<usize>,
    /// Next chunk to send.
    next: usize,
    /// The chunk the device expects next, as it last said.
    device_next: usize,
    /// The device's free room, samples, as it last said (after chunk `device_next - 1`).
    device_free: usize,
    /// Refusals still owed for chunks sent before the last go-back (the device answers in order,
    /// so they come before any answer to a chunk sent again): not new losses.
    stale_refusals: usize,
    /// Chunks sent again after a loss.
    resent: usize,
}

impl StreamFeed {
    /// The `StreamChunk`s of a record, the first `sent` of them taken by the device (the ring's
    /// fill at rest), which can take `free` samples more.
    pub fn new(chunks: Vec<HostMsg>, sent: usize, free: usize) -> Self {
        let mut before = Vec::with_capacity(chunks.len() + 1);
        let mut n = 0;
        before.push(0);
        for c in &chunks {
            if let HostMsg::StreamChunk { count, .. } = c {
                n += usize::from(*count);
            }
            before.push(n);
        }
        let sent = sent.min(chunks.len());
        Self {
            chunks,
            before,
            next: sent,
            device_next: sent,
            device_free: free,
            stale_refusals: 0,
            resent: 0,
        }
    }

    /// Samples in chunks `a..b`.
    fn samples(&self, a: usize, b: usize) -> usize {
        let at = |j: usize| {
            self.before
                .get(j.min(self.chunks.len()))
                .copied()
                .unwrap_or(0)
        };
        at(b).saturating_sub(at(a))
    }

    /// The room for chunks not yet sent, samples.
    pub fn credit(&self) -> usize {
        let in_flight = self.samples(self.device_next.min(self.next), self.next);
        self.device_free.saturating_sub(in_flight)
    }

    /// The next chunk to send, if the device can take it; counted as sent.
    pub fn due(&mut self) -> Option<HostMsg> {
        // A chunk in flight before a go-back may have been taken after all.
        self.next = self.next.max(self.device_next.min(self.chunks.len()));
        let m = *self.chunks.get(self.next)?;
        if self.samples(self.next, self.next + 1) > self.credit() {
            return None;
        }
        self.next += 1;
        Some(m)
    }

    /// The device answered chunk `seq`: it expects `next_seq`, it can take `free` more. A chunk
    /// it did not take (out of order: one before it was lost) sends the chunks from `next_seq`
    /// again, once per loss: the refusals of the chunks in flight behind it are expected.
    pub fn answered(&mut self, seq: u32, next_seq: u32, free: u32) {
        self.device_next = next_seq as usize;
        self.device_free = free as usize;
        if next_seq == seq.wrapping_add(1) {
            return;
        }
        if self.stale_refusals > 0 {
            self.stale_refusals -= 1;
            return;
        }
        if self.device_next < self.next {
            // The chunks sent after `seq` are refused too: owed, not new losses.
            let behind = self.next.saturating_sub(seq as usize + 1);
            self.go_back();
            self.stale_refusals = behind;
        }
    }

    /// The device's stream status (an answer to `StreamStatus`: the room after the chunks it took).
    pub fn status(&mut self, st: &StreamStatus) {
        self.device_next = st.next_seq as usize;
        self.device_free = st.free as usize;
    }

    /// No answer came for the chunks in flight: send them again from the one the device expects.
    pub fn go_back(&mut self) {
        let back = self.device_next.min(self.next);
        self.resent += self.next - back;
        self.stale_refusals = 0;
        self.next = back;
    }

    /// Chunks sent and not yet answered as taken.
    pub fn in_flight(&self) -> usize {
        self.next.saturating_sub(self.device_next)
    }

    /// The device has taken every chunk.
    pub fn done(&self) -> bool {
        self.device_next >= self.chunks.len()
    }

    /// Chunks sent again after a loss so far.
    pub fn resent(&self) -> usize {
        self.resent
    }
}

#[cfg(test)]
mod tests;
