use bincode::{Decode, Encode};

/// The eight magic bytes every dump starts with.
pub const MAGIC: &[u8; 8] = b"PDSDUMP1";
/// The only format version this crate reads and writes.
pub const VERSION: u32 = 1;
/// Largest accepted encoded header, in bytes.
pub const HEADER_LEN_MAX: usize = 65536;

/// Largest film, in pixels per frame (8192 × 8192).
pub const MAX_PIXELS: u64 = 1 << 26;
/// Largest number of frames.
pub const MAX_FRAMES: u64 = 1 << 20;

/// Record order promised by the producer (docs/format.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Order {
    Unspecified = 0,
    /// All samples of a pixel contiguous, pixels row by row, frames in turn.
    PixelMajor = 1,
    /// Sample s of every pixel of a frame before sample s + 1.
    PassMajor = 2,
}

impl std::fmt::Display for Order {
    /// As in JSON: `unspecified`, `pixel-major`, `pass-major`.
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(match self {
            Order::Unspecified => "unspecified",
            Order::PixelMajor => "pixel-major",
            Order::PassMajor => "pass-major",
        })
    }
}

impl Order {
    pub fn from_u8(v: u8) -> Option<Order> {
        match v {
            0 => Some(Order::Unspecified),
            1 => Some(Order::PixelMajor),
            2 => Some(Order::PassMajor),
            _ => None,
        }
    }
}

/// The dump header, in on-disk field order.
///
/// Invariants after [`Header::validate`]: `width, height, frames ≥ 1`,
/// `width × height ≤ 2^26`, `frames ≤ 2^20`, and the byte size of the
/// records fits in a `u64`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Header {
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub spp: u32,
    pub sample_count: u64,
    pub order: Order,
    pub scene: String,
    pub seed: u64,
    pub producer: String,
}

/// The wire form: `order` is a raw byte so that an unknown value is a
/// validation error rather than a decode error.
#[derive(Encode, Decode)]
struct WireHeader {
    width: u32,
    height: u32,
    frames: u32,
    spp: u32,
    sample_count: u64,
    order: u8,
    scene: String,
    seed: u64,
    producer: String,
}

fn config() -> impl bincode::config::Config {
    bincode::config::standard()
        .with_fixed_int_encoding()
        .with_little_endian()
        .with_limit::<HEADER_LEN_MAX>()
}

impl Header {
    /// A still (one frame) header with sensible defaults for the free-text fields.
    pub fn still(width: u32, height: u32, spp: u32, order: Order) -> Header {
        Header {
            width,
            height,
            frames: 1,
            spp,
            sample_count: 0,
            order,
            scene: String::new(),
            seed: 0,
            producer: format!("pathdensity {}", env!("CARGO_PKG_VERSION")),
        }
    }

    /// Pixels per frame.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// True when the dump animates (a 6-D joint space).
    pub fn animated(&self) -> bool {
        self.frames > 1
    }

    /// Encodes the header body (without magic, version and length).
    pub fn encode(&self) -> Vec<u8> {
        let wire = WireHeader {
            width: self.width,
            height: self.height,
            frames: self.frames,
            spp: self.spp,
            sample_count: self.sample_count,
            order: self.order as u8,
            scene: self.scene.clone(),
            seed: self.seed,
            producer: self.producer.clone(),
        };
        bincode::encode_to_vec(wire, config()).expect("header encoding into a Vec cannot fail")
    }

    /// Decodes a header body that must span exactly `bytes`.
    pub fn decode(bytes: &[u8]) -> Result<Header, String> {
        let (wire, used): (WireHeader, usize) = bincode::decode_from_slice(bytes, config())
            .map_err(|e| format!("header does not decode: {e}"))?;
        if used != bytes.len() {
            return Err(format!(
                "header_len is {} but the header decodes from {} bytes",
                bytes.len(),
                used
            ));
        }
        let order = Order::from_u8(wire.order)
            .ok_or_else(|| format!("unknown record order {}", wire.order))?;
        let h = Header {
            width: wire.width,
            height: wire.height,
            frames: wire.frames,
            spp: wire.spp,
            sample_count: wire.sample_count,
            order,
            scene: wire.scene,
            seed: wire.seed,
            producer: wire.producer,
        };
        h.validate()?;
        Ok(h)
    }

    /// Rejects absurd sizes before anything is allocated from them.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 || self.frames == 0 {
            return Err(format!(
                "film is {} × {} × {} frames; every size must be at least 1",
                self.width, self.height, self.frames
            ));
        }
        let pixels = self.width as u64 * self.height as u64;
        if pixels > MAX_PIXELS {
            return Err(format!(
                "film of {} × {} = {pixels} pixels exceeds the limit of 2^26 (8192 × 8192)",
                self.width, self.height
            ));
        }
        if self.frames as u64 > MAX_FRAMES {
            return Err(format!("{} frames exceed the limit of 2^20", self.frames));
        }
        if pixels.checked_mul(self.frames as u64).is_none() {
            return Err("width × height × frames overflows u64".into());
        }
        if self.sample_count.checked_mul(24).is_none() {
            return Err(format!(
                "sample_count {} makes 24 × sample_count overflow u64",
                self.sample_count
            ));
        }
        Ok(())
    }

    /// The complete prefix written before the records: magic, version,
    /// header length, header and zero padding up to the data offset.
    pub fn prefix_bytes(&self) -> Result<Vec<u8>, String> {
        self.validate()?;
        let body = self.encode();
        if body.len() > HEADER_LEN_MAX {
            return Err(format!(
                "encoded header is {} bytes, above the limit of {HEADER_LEN_MAX}",
                body.len()
            ));
        }
        let mut out = Vec::with_capacity(super::data_offset(body.len()));
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(body.len() as u32).to_le_bytes());
        out.extend_from_slice(&body);
        out.resize(super::data_offset(body.len()), 0);
        Ok(out)
    }
}
