//! Render parts (issue 16): a render split by *samples*. Part `i` of `n` traces samples
//! `SampleRange::part(i, n, spp)` of every pixel and keeps each pixel's **sum** over them; the
//! random numbers of a sample depend on its index only (the sampler is laid out for the whole
//! render's `spp`), so parts that tile `0..spp` hold exactly the samples of one render of all
//! of them, and [`merge`] adds their sums and divides by `spp`.
//!
//! A part is saved as a 32-bit float OpenEXR of the sums with a `raylume.part` text
//! attribute: the [`PartHeader`] as JSON, everything that decides the samples (the scene's
//! fingerprint, size, spp, bounces, seed, estimator, sampler, roulette) and the range. Parts
//! of different renders, gaps and overlaps are refused by [`merge`].
//!
//! How close is the merge to one render? One render adds each pixel's samples one after the
//! other in `f32` (batch after batch) and multiplies by `1/spp` once; the merge adds each
//! part's own running sum, then the parts' sums. Both sum the same `spp` non-negative-weighted
//! samples in different orders: each order's sum is within `(spp - 1) u S` of the exact sum
//! `S` of the magnitudes (u = 2^-24, first order; Higham, *Accuracy and Stability of Numerical
//! Algorithms*, 4.2), so the two differ by at most `2 (spp - 1) u S`, plus one rounding of
//! each product by `1/spp`: per channel `|merged - whole| <= (2 spp) u (sum of |samples|) /
//! spp`. Radiance samples are non-negative, so `sum of |samples| / spp` is the pixel value
//! itself: a relative bound of `2 spp u` (`merge_bound`). A single part of all the samples
//! merges to the render bit for bit.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::Error;

/// Samples `begin..end` of every pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SampleRange {
    /// The first sample.
    pub begin: u32,
    /// One past the last sample.
    pub end: u32,
}

impl SampleRange {
    /// Part `index` (1-based) of `count` equal ranges of `spp` samples: samples
    /// `(index - 1) * spp / count .. index * spp / count` (rounded down). Errors when `index`
    /// is not in `1..=count` or a part would be empty (`count > spp`).
    pub fn part(index: u32, count: u32, spp: u32) -> Result<SampleRange, Error> {
        if count == 0 || index == 0 || index > count {
            return Err(Error::Settings(format!(
                "part {index}/{count}: the part must be from 1 to the number of parts"
            )));
        }
        if count > spp {
            return Err(Error::Settings(format!(
                "part {index}/{count}: {count} parts of {spp} samples per pixel would leave some empty"
            )));
        }
        let at = |k: u32| (u64::from(k) * u64::from(spp) / u64::from(count)) as u32;
        Ok(SampleRange {
            begin: at(index - 1),
            end: at(index),
        })
    }

    /// Samples in the range.
    pub fn len(&self) -> u32 {
        self.end.saturating_sub(self.begin)
    }

    /// True when the range holds no sample.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// What a part belongs to and holds: every setting that decides its samples, and its range.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartHeader {
    /// The format (1).
    pub format: u32,
    /// A fingerprint of the scene (camera, materials, environment, geometry) as hex.
    pub scene: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel of the whole render.
    pub spp: u32,
    /// Bounces after the camera ray.
    pub max_bounces: u32,
    /// The random seed.
    pub seed: u32,
    /// `nee` or `plain`.
    pub estimator: String,
    /// `sobol`, `zsobol` or `independent`.
    pub sampler: String,
    /// The segment Russian roulette starts at, if it is on.
    pub russian_roulette: Option<u32>,
    /// Whether NEE sampled the environment by the learned guide (`Tracer::environment_guide`;
    /// `false` in parts written before it existed).
    #[serde(default)]
    pub environment_guide: bool,
    /// The samples this part holds.
    pub samples: SampleRange,
}

impl PartHeader {
    /// The settings that must agree between parts of one render, named, for error messages.
    fn identity(&self) -> [(&'static str, String); 10] {
        [
            ("format", self.format.to_string()),
            ("scene", self.scene.clone()),
            ("size", format!("{}x{}", self.width, self.height)),
            ("spp", self.spp.to_string()),
            ("bounces", self.max_bounces.to_string()),
            ("seed", self.seed.to_string()),
            ("estimator", self.estimator.clone()),
            ("sampler", self.sampler.clone()),
            ("russian roulette", format!("{:?}", self.russian_roulette)),
            ("environment guide", self.environment_guide.to_string()),
        ]
    }
}

/// A render part: its header and each pixel's sum over its samples (row-major, top row
/// first).
#[derive(Clone, Debug)]
pub struct Part {
    /// What the part belongs to and holds.
    pub header: PartHeader,
    /// Per pixel, the sum of its samples in the part's range.
    pub sums: Vec<[f32; 3]>,
}

/// The EXR attribute that holds a part's header.
const ATTRIBUTE: &str = "raylume.part";

impl Part {
    /// Writes the part as an OpenEXR of its sums with its header (nothing is left at `path`
    /// if it fails).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), Error> {
        use exr::prelude::*;
        let path = path.as_ref();
        let h = &self.header;
        let out_err = |reason: String| crate::Error::Output {
            path: path.to_path_buf(),
            reason,
        };
        if self.sums.len() != (h.width as usize) * (h.height as usize) {
            return Err(out_err(format!(
                "{} sums for a {}x{} image",
                self.sums.len(),
                h.width,
                h.height
            )));
        }
        let json = serde_json::to_string(h).map_err(|e| out_err(e.to_string()))?;
        let w = h.width as usize;
        let sums = &self.sums;
        let layer = Layer::new(
            (w, h.height as usize),
            LayerAttributes::named("raylume part: per-pixel sums"),
            Encoding::SMALL_LOSSLESS,
            SpecificChannels::rgb(|p: Vec2<usize>| {
                let v = sums[p.y() * w + p.x()];
                (v[0], v[1], v[2])
            }),
        );
        let mut image = Image::from_layer(layer);
        image.attributes.other.insert(
            Text::from(ATTRIBUTE),
            exr::meta::attribute::AttributeValue::Text(Text::from(json.as_str())),
        );
        let tmp = path.with_extension("exr.partial");
        image
            .write()
            .to_file(&tmp)
            .map_err(|e| out_err(e.to_string()))?;
        std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            out_err(e.to_string())
        })
    }

    /// Reads a part written by [`Part::save`]; an EXR without a part header is an error that
    /// says so.
    pub fn load(path: impl AsRef<Path>) -> Result<Part, Error> {
        use exr::prelude::*;
        let path = path.as_ref();
        let bad = |reason: String| crate::Error::Parts(format!("{}: {reason}", path.display()));
        let image = read_first_rgba_layer_from_file(
            path,
            |size, _| (size.width(), vec![[0.0f32; 3]; size.area()]),
            |(w, px): &mut (usize, Vec<[f32; 3]>),
             p: Vec2<usize>,
             (r, g, b, _a): (f32, f32, f32, f32)| {
                px[p.y() * *w + p.x()] = [r, g, b];
            },
        )
        .map_err(|e| bad(format!("not a readable OpenEXR file ({e})")))?;
        // exr files the header's custom attributes under the image or the layer on reading.
        let key = Text::from(ATTRIBUTE);
        let found = image
            .attributes
            .other
            .get(&key)
            .or_else(|| image.layer_data.attributes.other.get(&key));
        let header = match found {
            Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
            _ => {
                return Err(bad(
                    "not a raylume render part (no `raylume.part` header)".into()
                ));
            }
        };
        let header: PartHeader = serde_json::from_str(&header)
            .map_err(|e| bad(format!("a malformed part header ({e})")))?;
        let (w, sums) = image.layer_data.channel_data.pixels;
        if w != header.width as usize || sums.len() != w * header.height as usize {
            return Err(bad(format!(
                "the image is not the {}x{} its header says",
                header.width, header.height
            )));
        }
        if header.samples.is_empty() || header.samples.end > header.spp {
            return Err(bad(format!(
                "samples {}..{} are not a range within 0..{}",
                header.samples.begin, header.samples.end, header.spp
            )));
        }
        Ok(Part { header, sums })
    }
}

/// The relative bound on `|merged - whole render|` per channel of a merge of parts of an
/// `spp`-sample render (the module's docs derive it): what [`worst_relative_difference`] of
/// the merged image against the whole render stays within.
pub fn merge_bound(spp: u32) -> f64 {
    // 2 (spp - 1) u for the two orders of summation, 2 u for the two roundings of the
    // product by 1/spp: 2 spp u, u = f32::EPSILON / 2.
    f64::from(spp) * f64::from(f32::EPSILON)
}

/// The largest `|t - r| / |r|` over every channel of every pixel of `test` against
/// `reference` (paired in order; the shorter one's length counts): the quantity
/// [`merge_bound`] bounds for merged parts, or one render split over several GPUs, against a
/// single render. 0 where a channel is equal in both; infinite where they differ over a
/// zero reference or either is not a number, so such a pair is never within a bound.
pub fn worst_relative_difference(test: &[[f32; 3]], reference: &[[f32; 3]]) -> f64 {
    test.iter()
        .zip(reference)
        .flat_map(|(t, r)| t.iter().zip(r))
        .map(|(&t, &r)| {
            let (t, r) = (f64::from(t), f64::from(r));
            let d = (t - r).abs();
            if t == r {
                0.0
            } else if d.is_nan() {
                f64::INFINITY
            } else {
                d / r.abs()
            }
        })
        .fold(0.0, f64::max)
}

/// Joins parts of one render whose sample ranges follow each other without gap or overlap
/// into one part of their union (sums added, nothing divided): a part resumed with more
/// samples, or parts gathered to merge later. `names` label the parts in errors.
pub fn join(parts: &[Part], names: &[String]) -> Result<Part, Error> {
    let name = |i: usize| {
        names
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("part {}", i + 1))
    };
    let Some(first) = parts.first() else {
        return Err(Error::Parts("no parts to merge".into()));
    };
    let want = first.header.identity();
    for (i, p) in parts.iter().enumerate().skip(1) {
        for ((what, a), (_, b)) in want.iter().zip(p.header.identity()) {
            if *a != b {
                return Err(Error::Parts(format!(
                    "{} is of another render than {}: {what} {b} against {a}",
                    name(i),
                    name(0)
                )));
            }
        }
    }
    let mut order: Vec<usize> = (0..parts.len()).collect();
    order.sort_by_key(|&i| (parts[i].header.samples.begin, parts[i].header.samples.end));
    let begin = parts[order[0]].header.samples.begin;
    let mut next = begin;
    for &i in &order {
        let r = parts[i].header.samples;
        if r.begin > next {
            return Err(Error::Parts(format!(
                "samples {next}..{} of every pixel are in no part (missing a part?)",
                r.begin
            )));
        }
        if r.begin < next {
            return Err(Error::Parts(format!(
                "{} (samples {}..{}) overlaps the samples before it, up to {next}",
                name(i),
                r.begin,
                r.end
            )));
        }
        next = r.end;
    }
    let mut sums = vec![[0.0f32; 3]; first.sums.len()];
    for &i in &order {
        for (o, s) in sums.iter_mut().zip(&parts[i].sums) {
            for k in 0..3 {
                o[k] += s[k];
            }
        }
    }
    let mut header = first.header.clone();
    header.samples = SampleRange { begin, end: next };
    Ok(Part { header, sums })
}

/// Merges parts of one render into its image (each pixel's mean over all `spp` samples):
/// the parts must be of the same render (the same header but for the range) and their
/// ranges must tile `0..spp` without gap or overlap ([`join`]); `names` label them in errors.
pub fn merge(parts: &[Part], names: &[String]) -> Result<(PartHeader, Vec<[f32; 3]>), Error> {
    let joined = join(parts, names)?;
    let (r, spp) = (joined.header.samples, joined.header.spp);
    if r.begin > 0 {
        return Err(Error::Parts(format!(
            "samples 0..{} of every pixel are in no part (missing a part?)",
            r.begin
        )));
    }
    if r.end != spp {
        return Err(Error::Parts(format!(
            "samples {}..{spp} of every pixel are in no part (missing a part?)",
            r.end
        )));
    }
    let scale = 1.0 / spp as f32;
    let mut out = joined.sums;
    for o in &mut out {
        for v in o.iter_mut() {
            *v *= scale;
        }
    }
    Ok((joined.header, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn worst_relative_difference_is_the_largest_channel_error_relative_to_the_reference() {
        let r = [[1.0, 2.0, 0.0], [4.0, 0.5, 8.0]];
        assert_eq!(worst_relative_difference(&r, &r), 0.0);
        // 2.0 -> 2.5 is 0.25 of its channel; 8.0 -> 7.0 is 0.125.
        let t = [[1.0, 2.5, 0.0], [4.0, 0.5, 7.0]];
        assert_eq!(worst_relative_difference(&t, &r), 0.25);
        // Anything but equality over a zero reference, and a NaN on either side, is never
        // within a bound.
        let t = [[1.0, 2.0, 1e-30], [4.0, 0.5, 8.0]];
        assert_eq!(worst_relative_difference(&t, &r), f64::INFINITY);
        let t = [[1.0, 2.0, 0.0], [f32::NAN, 0.5, 8.0]];
        assert_eq!(worst_relative_difference(&t, &r), f64::INFINITY);
        assert_eq!(worst_relative_difference(&r, &t), f64::INFINITY);
        assert!(worst_relative_difference(&r, &r) <= merge_bound(1));
    }
}
