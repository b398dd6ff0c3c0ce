//! Inertial operation and processing (§4.2.3, §4.3.2–4.3.3): six 12-bit channels per board
//! (three gyroscope, three accelerometer axes) sent as 6-bit delta-modulation codes, each
//! protected by an extended Hamming code (single-error correction, double-error detection),
//! interleaved across the six channels and scrambled with a pseudo-random sequence; decoded
//! counts become physical values through a linear per-axis calibration (zero and slope)
//! found from ±g static poses and ±45 rpm turntable runs.
//!
//! The thesis gives the ingredients but not the code layout; the layout here is ours: 6 codes
//! × 11 bits = 66 bits per board and frame (9.2 kbit/s at 140 Hz, within the 13 kbit/s link).
//! A frame with an uncorrectable code is flagged (`None`); the decoder then assumes each lost
//! delta equals the channel's previous delta (the signals are smooth at 140 Hz), so one lost
//! frame costs a second difference of the deltas — for the noise-shaped code a permanent
//! offset of about 0.7 step, which the key frames (beyond the thesis:
//! [`DeltaCodec::with_key_interval`]) remove by sending each channel's absolute
//! count in place of two of its deltas every K frames.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use skin_core::check::{finite, positive};

/// Channels per board: gyroscope x, y, z, accelerometer x, y, z.
pub(crate) const CHANNELS: usize = 6;
/// Bits per encoded board frame.
pub(crate) const FRAME_BITS: usize = CHANNELS * 11;
/// Largest 12-bit count.
const MAX_COUNT: i32 = 4095;
/// Largest delta of the 6-bit code (two's complement, −32..=31 counts per frame).
pub(crate) const DELTA_MAX: i32 = 31;
/// Smallest delta of the 6-bit code.
pub(crate) const DELTA_MIN: i32 = -32;
/// The shortest key interval ([`DeltaCodec::with_key_interval`]): two key frames per channel.
pub(crate) const MIN_KEY_INTERVAL: u32 = 2 * CHANNELS as u32;
/// A decoded count at or above this is at full scale: 4092 = 4 × 1023 is the largest sum of
/// four 10-bit samples (§4.2.3's accumulation), 4095 the largest 12-bit count.
pub(crate) const FULL_SCALE_HIGH: i32 = 4 * 1023;
/// A decoded count at or below this is at the bottom of the scale.
pub(crate) const FULL_SCALE_LOW: i32 = 0;

/// Why a decoded channel is a bound rather than a reading (beyond the thesis, which does not
/// discuss either: what a decoder of a real suit has to know).
///
/// - **Clipped**: the decoded count is at the converter's full scale (at or below 0, at or
///   above 4092 = 4 × 1023, the largest sum of four 10-bit samples); the quantity may be
///   anywhere beyond it.
/// - **Slew-saturated**: the frame's delta is at the 6-bit code's extreme (−32 or +31 code units);
///   the encoder clamps larger changes, so the true count may be further
///   still and the reconstruction lags it. A delta inside the code's range means the
///   decoder's count is the encoder's exactly, so only the extremes are flagged.
/// - **Unsynced** (only with key frames,
///   [`DeltaCodec::with_key_interval`]): the decoder's count may be off the encoder's — a
///   code of the channel was lost (uncorrectable) since the channel's last key frame, or the
///   frame is one of the channel's two key frames (which carry its absolute count, not a
///   delta, so the frame has no current reading of it). Cleared by the next key frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Saturation {
    /// The count is at full scale.
    pub clipped: bool,
    /// The delta is at the code's extreme.
    pub slew: bool,
    /// The count is not a current reading in step with the encoder's (lost code since the
    /// last key frame, or a key frame).
    #[serde(default)]
    pub unsynced: bool,
}

impl Saturation {
    /// Any flag.
    pub fn any(&self) -> bool {
        self.clipped || self.slew || self.unsynced
    }

    /// The flags of a decoded `count` reached by `delta` (in step with the encoder).
    pub fn of(count: i32, delta: i32) -> Self {
        Saturation {
            clipped: count <= FULL_SCALE_LOW || count >= FULL_SCALE_HIGH,
            slew: delta <= DELTA_MIN || delta >= DELTA_MAX,
            unsynced: false,
        }
    }
}

/// Linear calibration of one axis: `value = (count − zero) / slope` (§4.3.3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AxisCalibration {
    /// Count at zero input.
    pub zero: f64,
    /// Counts per unit (per m/s² or per rad/s).
    pub slope: f64,
}

impl AxisCalibration {
    /// From the mean counts with the axis along (+) and against (−) a known reference
    /// (gravity for accelerometers, the 45 rpm turntable for gyroscopes): the zero is their
    /// mean, the slope their half difference over the reference.
    ///
    /// # Errors
    /// [`Error::Core`] (invalid parameter) for non-finite means or a non-positive reference;
    /// [`Error::InvalidParam`] if the two means coincide.
    pub fn from_opposite(mean_plus: f64, mean_minus: f64, reference: f64) -> Result<Self> {
        finite("mean_plus", mean_plus)?;
        finite("mean_minus", mean_minus)?;
        positive("reference", reference)?;
        let slope = (mean_plus - mean_minus) / (2.0 * reference);
        if slope.abs() < 1e-12 {
            return Err(Error::InvalidParam {
                name: "mean_plus",
                reason: "equal to mean_minus: the axis does not respond".into(),
            });
        }
        Ok(AxisCalibration {
            zero: 0.5 * (mean_plus + mean_minus),
            slope,
        })
    }

    /// Physical value of a count.
    pub fn value(&self, count: f64) -> f64 {
        (count - self.zero) / self.slope
    }
}

/// Extended Hamming (11, 6): parity bits at positions 1, 2, 4, 8, data at 3, 5, 6, 7, 9, 10,
/// overall parity at 0.
const DATA_POS: [u32; 6] = [3, 5, 6, 7, 9, 10];

fn hamming_encode(data: u8) -> u16 {
    let mut w = 0u16;
    for (i, &p) in DATA_POS.iter().enumerate() {
        if data >> i & 1 == 1 {
            w |= 1 << p;
        }
    }
    for p in [1u32, 2, 4, 8] {
        let parity = (1..11u32)
            .filter(|&k| k & p != 0 && k != p)
            .fold(0, |acc, k| acc ^ (w >> k & 1));
        w |= parity << p;
    }
    w | ((w.count_ones() & 1) as u16)
}

/// Decoded data, or `None` for a detected double error.
fn hamming_decode(w: u16) -> Option<u8> {
    let syndrome = (1..11u32)
        .filter(|&k| w >> k & 1 == 1)
        .fold(0u32, |acc, k| acc ^ k);
    let overall = w.count_ones() & 1;
    let w = match (syndrome, overall) {
        (0, 0) => w,
        (0, _) => w ^ 1,
        (s, 1) if s < 11 => w ^ (1 << s),
        _ => return None,
    };
    Some(
        DATA_POS
            .iter()
            .enumerate()
            .fold(0u8, |acc, (i, &p)| acc | (((w >> p & 1) as u8) << i)),
    )
}

/// The scrambling sequence: a 7-bit maximal-length LFSR (x⁷ + x⁶ + 1), restarted each frame.
fn scramble(bits: &mut [bool]) {
    let mut s = 0x5Bu8;
    for b in bits {
        let out = (s >> 6 ^ s >> 5) & 1;
        s = (s << 1 | out) & 0x7F;
        *b ^= out == 1;
    }
}

/// Delta-modulation encoder/decoder state of one board (six channels).
///
/// Two readings of §4.2.3's "6-bit values using delta modulation" (the thesis gives no
/// step size or code layout):
///
/// - [`DeltaCodec::new`] (the type's `Default`; the simulator's front end with
///   `SimulationParams::delta_step` `None`): each code is the change of the 12-bit count in
///   whole counts, clamped to −32..=31. Small changes are sent exactly; a change beyond 31 counts
///   per frame slews (42 rad/s² at ±20 rad/s), and the reconstruction lags until it catches up.
/// - [`DeltaCodec::noise_shaped`] (with 16-count units the
///   simulator's default, `SimulationParams::delta_step`): each code
///   counts `step` counts and the encoder feeds its round-off back, so a frame that
///   under-reads is followed by one that over-reads — the thesis's own description ("if the
///   6-bit round-off underestimates the acceleration in one frame, it will compensate by
///   overestimating in the next frame; if we were to double-integrate … the resulting
///   position would have more than 6 bits of precision"). Each frame is then accurate to
///   within `step` counts (σ step/√6, below), the running sum of the decoded counts to a bounded error, and the slew
///   is `31 · step` counts per frame. With `step` 1 it equals the whole-count code until a
///   change slews; the whole-count code keeps no feedback, so a slewed change is not made up
///   later.
///
/// **The noise-shaped code's per-frame error** (what the filter
/// must be told, [`DeltaCodec::frame_error_sigma_counts`]). Write `c_k` for the count the
/// encoder is given in frame k, `r_k` for the reconstruction both ends hold after it, and
/// `E_k = Σ_{i≤k} (c_i − r_i)` for the encoder's accumulated error. The encoder sends
/// `u_k = round((c_k + E_{k−1} − r_{k−1}) / step)` units, so `r_k = r_{k−1} + step · u_k`
/// and `E_k = (c_k + E_{k−1} − r_{k−1}) − step · u_k`, the round-off of that division:
/// `|E_k| ≤ step/2` while nothing slews. Hence the decoded count is
/// `r_k = c_k + E_{k−1} − E_k` — the *difference of two successive round-offs*:
///
/// - per frame, `|r_k − c_k| ≤ step` (not `step/2`: the two round-offs may have opposite
///   signs);
/// - if the round-offs are uniform on ±step/2 and independent from frame to frame (the
///   signal moves by several units between frames, or carries at least a count of noise), the
///   per-frame error has mean 0 and variance `2 · step²/12`, i.e. **σ = step/√6** counts;
/// - it is negatively correlated at lag 1: `cov(E_{k−1} − E_k, E_k − E_{k+1}) = −step²/12`,
///   correlation −½, and zero beyond. The sum over n frames telescopes to `E_0 − E_n`, so its
///   σ stays step/√6 for any n (white noise of the same σ would grow as √n): a filter that
///   treats the error as white is conservative about the integrated reading, and the mean of
///   two successive frames has σ = step/(2√6), half a frame's, not 1/√2 of it.
///
/// **Key frames** (beyond the thesis, which describes no
/// resynchronisation — [`DeltaCodec::with_key_interval`]). A lost frame (an uncorrectable
/// code) leaves the decoder's reconstruction off the encoder's for good: it can only repeat
/// the previous delta, and successive noise-shaped deltas differ by the round-offs' second
/// difference (σ ≈ 0.7 step) — at a bit error rate of 10⁻² the 16-count code lost the pose.
/// Within the thesis's frame (6 bits per channel per frame, 66 bits with the ECC, nothing
/// widened), every `K` frames each channel sends, in place of two deltas, the 12-bit count
/// `x = r_{k−1}` both ends hold before the key (brought into 0..=4095 on both): frame k its
/// high six bits, frame k+1 its low six bits. Through the two key frames both ends
/// extrapolate by the channel's last delta (`r = x + 2·δ·step` after them); after the second
/// half the encoder drops its carried round-off (`E = 0`), so the first delta after a key
/// spans one frame of motion plus the extrapolation's miss, not two or three frames (fewer
/// slews on the walk's arm). A decoder off the encoder (a code of the channel lost since
/// its last key) takes `x` and the same extrapolation, and is then in step exactly — if both
/// halves and the delta before them (the extrapolation's δ) arrived; otherwise it waits for
/// the next key. For a decoder in step the key is redundant: a lost half costs it nothing,
/// and the key checks it — if its own count differs from `x`, a code was mis-corrected
/// (three bit errors in one code pass the extended Hamming code as one) since the last
/// key, more likely one of the K deltas than one of the two halves, so `x` is taken but the
/// channel stays flagged until the next key confirms it (a wrong high half would be off by
/// a multiple of 64 counts). The channels' keys are staggered (`⌊c·K/6⌋` frames apart) so a
/// frame never loses more than one channel's delta. The decoder flags a channel
/// [`Saturation::unsynced`] on its two key frames (extrapolated, no reading) and while it is
/// off the encoder. Without key frames the decoder advances every channel by its previous
/// delta when any code is lost; with them each channel whose code arrived takes its own
/// delta, so a lost code unsyncs only its channel. Costs: two of every K readings per
/// channel (flagged, skipped by the filter); a mis-corrected delta still leaves a wrong count
/// unflagged until the next key (without keys: for good). The per-frame error of the
/// unflagged frames is unchanged: the first delta frame after a key has `r = c − E` with the
/// carried error reset (`|r − c| ≤ step/2`), every later one `c + E_{k−1} − E_k` as derived
/// above, so [`frame_error_sigma_counts`](Self::frame_error_sigma_counts) (step/√6) and
/// [`frame_error_bound_counts`](Self::frame_error_bound_counts) (step) still hold — the
/// σ slightly over-states the first frame after a key, the safe side; the telescoping of
/// the running sum restarts at each key. K = 28 (0.2 s at 140 Hz) is the simulator's
/// default (`SimulationParams::key_interval`, chosen from the bit-error sweep of
/// `examples/inertial_capture -- --ber-sweep`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeltaCodec {
    recon: [i32; CHANNELS],
    last_delta: [i32; CHANNELS],
    /// Counts per code unit (1 for the default codec).
    #[serde(default = "unit_step")]
    step: i32,
    /// Whether the encoder feeds its round-off back (noise shaping).
    #[serde(default)]
    shaped: bool,
    /// The encoder's accumulated error, Σ (count − reconstruction), per channel.
    #[serde(default)]
    error: [i32; CHANNELS],
    /// Frames between a channel's key frames (0: no key frames, the thesis's code).
    #[serde(default)]
    key_interval: u32,
    /// Frames encoded (or decoded) so far: both ends of a link count alike, lost frames too.
    #[serde(default)]
    frame: u64,
    /// The key value in flight per channel: the encoder's absolute count sent in halves, or
    /// the decoder's received high half (`None` if that code was lost).
    #[serde(default)]
    key: [Option<i32>; CHANNELS],
    /// Decoder: a code of the channel was lost since its last key frame.
    #[serde(default)]
    unsynced: [bool; CHANNELS],
    /// Decoder: its count at the channel's last first-half key frame (what the encoder sends
    /// if both are in step).
    #[serde(default)]
    key_check: [i32; CHANNELS],
    /// Decoder: the channel's last delta was received (so it equals the encoder's).
    #[serde(default)]
    delta_known: [bool; CHANNELS],
    /// Decoder: the last frame's count is not a current reading in step with the encoder
    /// (unsynced, or one of the channel's key frames).
    #[serde(default)]
    stale: [bool; CHANNELS],
}

fn unit_step() -> i32 {
    1
}

impl Default for DeltaCodec {
    fn default() -> Self {
        DeltaCodec {
            recon: [2048; CHANNELS],
            last_delta: [0; CHANNELS],
            step: 1,
            shaped: false,
            error: [0; CHANNELS],
            key_interval: 0,
            frame: 0,
            key: [None; CHANNELS],
            unsynced: [false; CHANNELS],
            key_check: [0; CHANNELS],
            delta_known: [true; CHANNELS],
            stale: [false; CHANNELS],
        }
    }
}

impl DeltaCodec {
    /// A codec at mid-scale (both ends start from count 2048): whole-count deltas, no
    /// feedback.
    pub fn new() -> Self {
        Self::default()
    }

    /// A noise-shaped codec whose code unit is `step` counts (see the type's docs); both
    /// ends of a link must use the same step.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] unless `step` is in 1..=128.
    pub fn noise_shaped(step: i32) -> Result<Self> {
        if !(1..=128).contains(&step) {
            return Err(Error::InvalidParam {
                name: "step",
                reason: format!("{step} is not in 1..=128 counts"),
            });
        }
        Ok(DeltaCodec {
            step,
            shaped: true,
            ..Self::default()
        })
    }

    /// Counts per code unit: 1 for the whole-count code, `step` for
    /// [`noise_shaped`](Self::noise_shaped).
    pub fn step(&self) -> i32 {
        self.step
    }

    /// Whether the encoder feeds its round-off back (the noise-shaped code).
    pub fn is_noise_shaped(&self) -> bool {
        self.shaped
    }

    /// This codec with a key frame every `frames` frames per channel (beyond the thesis, which
    /// describes no resynchronisation — see the type's docs, "Key frames"); 0 turns them off. Both
    /// ends of a link must use the same interval and start together (they count frames alike, lost
    /// ones too).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] unless `frames` is 0 or in 12..=1,000,000 (two key frames
    /// for each of the six channels, so that no two channels key in the same frame).
    pub fn with_key_interval(self, frames: u32) -> Result<Self> {
        if frames != 0 && !(MIN_KEY_INTERVAL..=1_000_000).contains(&frames) {
            return Err(Error::InvalidParam {
                name: "key_interval",
                reason: format!("{frames} is neither 0 (off) nor in 12..=1000000 frames"),
            });
        }
        Ok(DeltaCodec {
            key_interval: frames,
            ..self
        })
    }

    /// Frames between a channel's key frames; 0 if the code has none.
    pub fn key_interval(&self) -> u32 {
        self.key_interval
    }

    /// Channel `c`'s place in its key cycle in the current frame: `Some(0)` for the frame
    /// carrying the high six bits of its absolute count, `Some(1)` for the low six bits,
    /// `None` for a delta frame. Channel c's keys are offset by `⌊c · K / 6⌋` frames, so the
    /// six channels' keys are spread over the interval, and with K ≥ 12 no two overlap (nor
    /// does any second half fall on frame 0, before its first half was sent).
    fn key_phase(&self, c: usize) -> Option<u8> {
        if self.key_interval == 0 {
            return None;
        }
        let k = u64::from(self.key_interval);
        let offset = c as u64 * k / CHANNELS as u64;
        match (self.frame + k - offset) % k {
            0 => Some(0),
            1 => Some(1),
            _ => None,
        }
    }

    /// σ of one decoded frame's error against the encoder's count, in counts, while the code
    /// does not slew: `step/√6` for the noise-shaped code (the difference of two successive
    /// round-offs, each uniform on ±step/2; derivation in the type's docs), 0 for the
    /// whole-count code (a delta inside its range is exact). Its lag-1 correlation is −½
    /// (type docs); the per-frame error itself is bounded by
    /// [`frame_error_bound_counts`](Self::frame_error_bound_counts).
    pub fn frame_error_sigma_counts(&self) -> f64 {
        if self.shaped {
            f64::from(self.step) / 6f64.sqrt()
        } else {
            0.0
        }
    }

    /// The largest per-frame error of a decoded count against the encoder's, in counts, while
    /// nothing slews and no frame is lost: `step` for the noise-shaped code (two round-offs of
    /// at most step/2 each), 0 for the whole-count code.
    pub fn frame_error_bound_counts(&self) -> i32 {
        if self.shaped {
            self.step
        } else {
            0
        }
    }

    /// Encodes one frame of six 12-bit counts into 66 scrambled, interleaved, error-protected
    /// bits (six 11-bit codes); the 6-bit deltas saturate at −32..=31 counts per frame and carry
    /// their round-off into the next frame.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a count outside 0..=4095.
    pub fn encode(&mut self, counts: &[i32; CHANNELS]) -> Result<[bool; FRAME_BITS]> {
        let mut codes = [0u16; CHANNELS];
        for c in 0..CHANNELS {
            if !(0..=MAX_COUNT).contains(&counts[c]) {
                return Err(Error::InvalidParam {
                    name: "counts",
                    reason: format!("{} is not a 12-bit count", counts[c]),
                });
            }
            match self.key_phase(c) {
                Some(0) => {
                    // Key frame, first half: the high six bits of the count both ends hold
                    // (brought into the 12-bit range on both); the reconstruction then
                    // extrapolates by the last delta through both key frames.
                    self.recon[c] = self.recon[c].clamp(0, MAX_COUNT);
                    self.key[c] = Some(self.recon[c]);
                    codes[c] = hamming_encode((self.recon[c] >> 6 & 0x3F) as u8);
                    self.recon[c] += self.last_delta[c] * self.step;
                    continue;
                }
                Some(_) => {
                    // Second half: the low six bits; the encoder starts afresh (no round-off
                    // carried over the key: the first delta after it is exact to step/2).
                    let x = self.key[c].unwrap_or(self.recon[c]);
                    codes[c] = hamming_encode((x & 0x3F) as u8);
                    self.recon[c] += self.last_delta[c] * self.step;
                    self.error[c] = 0;
                    continue;
                }
                None => {}
            }
            let delta = if self.shaped {
                let want = counts[c] + self.error[c] - self.recon[c];
                let units = (f64::from(want) / f64::from(self.step)).round() as i32;
                units.clamp(DELTA_MIN, DELTA_MAX)
            } else {
                (counts[c] - self.recon[c]).clamp(DELTA_MIN, DELTA_MAX)
            };
            self.recon[c] += delta * self.step;
            self.last_delta[c] = delta;
            if self.shaped {
                self.error[c] += counts[c] - self.recon[c];
            }
            codes[c] = hamming_encode((delta & 0x3F) as u8);
        }
        self.frame += 1;
        let mut bits = [false; FRAME_BITS];
        for (c, code) in codes.iter().enumerate() {
            for i in 0..11 {
                bits[i * CHANNELS + c] = code >> i & 1 == 1;
            }
        }
        scramble(&mut bits);
        Ok(bits)
    }

    /// Decodes one frame; `None` (a flagged frame) if a code has an uncorrectable error, in
    /// which case every channel advances by its previous delta — without key frames; with
    /// them ([`with_key_interval`](Self::with_key_interval)) the channels whose codes are
    /// intact take their own delta or key half, and only the lost channels advance by their
    /// previous delta and are flagged unsynced until their next key frame
    /// ([`saturation`](Self::saturation)). The number of corrected bit errors is returned
    /// with the counts.
    pub fn decode(&mut self, bits: &[bool; FRAME_BITS]) -> Option<([i32; CHANNELS], usize)> {
        let mut b = *bits;
        scramble(&mut b);
        let mut deltas = [0i32; CHANNELS];
        let mut data = [None; CHANNELS];
        let mut corrected = 0;
        let mut ok = true;
        for (c, delta) in deltas.iter_mut().enumerate() {
            let w = (0..11).fold(0u16, |acc, i| acc | (u16::from(b[i * CHANNELS + c]) << i));
            match hamming_decode(w) {
                Some(d) => {
                    if hamming_encode(d) != w {
                        corrected += 1;
                    }
                    data[c] = Some(d);
                    // Sign-extend the 6-bit two's complement delta.
                    *delta = i32::from(((d << 2) as i8) >> 2);
                }
                None => ok = false,
            }
        }
        if self.key_interval > 0 {
            return self.decode_keyed(&data, corrected, ok);
        }
        self.frame += 1;
        if !ok {
            for c in 0..CHANNELS {
                self.recon[c] =
                    (self.recon[c] + self.last_delta[c] * self.step).clamp(0, MAX_COUNT);
            }
            return None;
        }
        for (r, d) in self.recon.iter_mut().zip(&deltas) {
            *r += d * self.step;
        }
        self.last_delta = deltas;
        Some((self.recon, corrected))
    }

    /// The saturation flags of the last frame [`decode`](Self::decode) returned, per channel
    /// (gyroscope x, y, z, accelerometer x, y, z).
    pub fn saturation(&self) -> [Saturation; CHANNELS] {
        std::array::from_fn(|c| Saturation {
            unsynced: self.stale[c],
            ..Saturation::of(self.recon[c], self.last_delta[c])
        })
    }

    /// [`decode`](Self::decode) with key frames: `data` holds each channel's decoded 6-bit
    /// code (`None`: uncorrectable).
    fn decode_keyed(
        &mut self,
        data: &[Option<u8>; CHANNELS],
        corrected: usize,
        ok: bool,
    ) -> Option<([i32; CHANNELS], usize)> {
        for (c, d) in data.iter().enumerate() {
            let step = self.last_delta[c] * self.step;
            match self.key_phase(c) {
                Some(0) => {
                    self.recon[c] = self.recon[c].clamp(0, MAX_COUNT);
                    self.key_check[c] = self.recon[c];
                    self.key[c] = d.map(|d| i32::from(d) << 6);
                    self.recon[c] += step;
                }
                Some(_) => {
                    self.recon[c] += step;
                    match (self.key[c], d) {
                        (Some(high), Some(low)) if self.delta_known[c] => {
                            let x = high | i32::from(*low);
                            // In step, the decoder held the key's count already; if it did
                            // not, a code was mis-corrected (three bit errors pass the
                            // extended Hamming code as one) since the last key — more likely
                            // one of the K deltas than one of the two halves, so the key is
                            // taken, but flagged until the next key confirms it.
                            self.unsynced[c] = !self.unsynced[c] && self.key_check[c] != x;
                            self.recon[c] = x + 2 * step;
                        }
                        // A lost half leaves a channel in step as it was (the key carries
                        // nothing new to it), an unsynced one unsynced.
                        _ => self.unsynced[c] |= !self.delta_known[c],
                    }
                }
                None => match d {
                    Some(d) => {
                        let delta = i32::from(((d << 2) as i8) >> 2);
                        // As the encoder: unclamped, so both ends stay equal.
                        self.recon[c] += delta * self.step;
                        self.last_delta[c] = delta;
                        self.delta_known[c] = true;
                    }
                    None => {
                        self.recon[c] += step;
                        self.unsynced[c] = true;
                        self.delta_known[c] = false;
                    }
                },
            }
            self.stale[c] = self.unsynced[c] || self.key_phase(c).is_some();
        }
        self.frame += 1;
        ok.then_some((self.recon, corrected))
    }
}

#[cfg(test)]
mod tests;
