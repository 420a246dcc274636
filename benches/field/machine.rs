//! The machine a `field` bench ran on, and its ceilings: CPU model, ISA, cache, the FMA peak
//! and a STREAM-like triad bandwidth, plus the wall-clock and CPU-time clock every figure of
//! the bench is printed with.

use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;

/// CPU seconds used by this process so far (all threads), from `/proc/self/task/*/schedstat`
/// (nanoseconds on a CPU). `None` where that is unavailable.
pub(crate) fn cpu_seconds() -> Option<f64> {
    let mut total = 0u64;
    for e in std::fs::read_dir("/proc/self/task").ok()? {
        let p = e.ok()?.path().join("schedstat");
        let s = std::fs::read_to_string(p).ok()?;
        total += s.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total as f64 * 1e-9)
}

pub(crate) fn loadavg() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "n/a".into())
}

/// Wall and CPU time of a region.
pub(crate) struct Clock {
    pub(crate) wall: Instant,
    cpu: Option<f64>,
}

impl Clock {
    pub(crate) fn start() -> Self {
        Self {
            cpu: cpu_seconds(),
            wall: Instant::now(),
        }
    }
    /// (wall seconds, CPU seconds or wall × threads when unavailable).
    pub(crate) fn stop(&self) -> (f64, f64) {
        let w = self.wall.elapsed().as_secs_f64();
        let threads = rayon::current_num_threads() as f64;
        let c = match (self.cpu, cpu_seconds()) {
            (Some(a), Some(b)) => b - a,
            _ => w * threads,
        };
        (w, c)
    }
}

/// "X/s wall, Y/s per CPU·threads".
pub(crate) fn rate(count: f64, wall: f64, cpu: f64) -> String {
    let threads = rayon::current_num_threads() as f64;
    format!(
        "{:>9.0}/s wall, {:>9.0}/s on {} idle cores (CPU-time normalised)",
        count / wall,
        count / cpu * threads,
        threads
    )
}

/// The FMA chains [`fma_thread`] runs in this build.
pub(crate) fn fma_isa() -> &'static str {
    if cfg!(all(target_arch = "x86_64", target_feature = "avx512f")) {
        "AVX-512 FMA chains"
    } else if cfg!(all(
        target_arch = "x86_64",
        target_feature = "avx2",
        target_feature = "fma"
    )) {
        "AVX2 FMA chains (8-wide mul_add)"
    } else if cfg!(target_arch = "aarch64") {
        "NEON FMA chains (mul_add)"
    } else {
        "portable mul_add chains (no FMA in this build)"
    }
}

/// The value of the first `/proc/cpuinfo` line whose key is `key` (Linux; `None` elsewhere).
pub(crate) fn cpuinfo(key: &str) -> Option<String> {
    let t = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    t.lines()
        .find(|l| l.split(':').next().map(str::trim) == Some(key))
        .and_then(|l| l.split(':').nth(1))
        .map(|v| v.trim().to_string())
}

/// The last-level (L3) cache of CPU 0 as sysfs states it (e.g. "32768K"), Linux only.
pub(crate) fn l3_cache() -> Option<String> {
    let dir = std::path::Path::new("/sys/devices/system/cpu/cpu0/cache");
    (0..8).find_map(|i| {
        let idx = dir.join(format!("index{i}"));
        let level = std::fs::read_to_string(idx.join("level")).ok()?;
        (level.trim() == "3")
            .then(|| std::fs::read_to_string(idx.join("size")).ok())
            .flatten()
            .map(|v| v.trim().to_string())
    })
}

/// Prints the machine: CPU model (with family and model numbers, which name the core
/// generation where the model string does not, e.g. "AMD EPYC" on a VM), L3, build and CPU ISA
/// features.
pub(crate) fn machine() {
    let mut model = cpuinfo("model name").unwrap_or_else(|| "unknown (no /proc/cpuinfo)".into());
    if let (Some(f), Some(m)) = (cpuinfo("cpu family"), cpuinfo("model")) {
        model = format!("{model} (family {f}, model {m})");
    }
    if let Some(l3) = l3_cache() {
        model = format!("{model}, L3 {l3}");
    }
    let build: Vec<&str> = [
        ("avx512f", cfg!(target_feature = "avx512f")),
        ("avx2", cfg!(target_feature = "avx2")),
        ("fma", cfg!(target_feature = "fma")),
        ("sse4.2", cfg!(target_feature = "sse4.2")),
        ("neon", cfg!(target_feature = "neon")),
    ]
    .into_iter()
    .filter(|f| f.1)
    .map(|f| f.0)
    .collect();
    #[allow(unused_mut)]
    let mut cpu: Vec<&str> = Vec::new();
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            cpu.push("avx512f");
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            cpu.push("avx2");
        }
        if std::arch::is_x86_feature_detected!("fma") {
            cpu.push("fma");
        }
    }
    println!(
        "== machine: {model}; {} threads; build uses [{}]; CPU has [{}] ==",
        rayon::current_num_threads(),
        build.join(", "),
        cpu.join(", ")
    );
}

/// The f32 kernel `matrixmultiply` picks on this CPU, by the crate's own rule (0.3.11,
/// `src/sgemm_kernel.rs`, `detect`, run time): AVX-512F when its `avx512` feature is on (a
/// default feature, which this project keeps) and the CPU has it, else AVX2 + FMA, else AVX, else
/// its portable one (aarch64: NEON). `MMTEST_FEATURE`, a comma-separated list read when the crate
/// is compiled (`src/target_features.rs`), limits it to the features named there: building with
/// `MMTEST_FEATURE=avx,avx2,fma` makes an AVX-512 CPU run the kernel an AVX2-only CPU runs.
pub(crate) fn matrixmultiply_kernel() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        let allowed = |f: &str| match option_env!("MMTEST_FEATURE") {
            None | Some("") => true,
            Some(list) => list.split(',').any(|x| x.trim() == f),
        };
        let has = |f: &str| {
            allowed(f)
                && match f {
                    "avx512f" => std::arch::is_x86_feature_detected!("avx512f"),
                    "avx2" => std::arch::is_x86_feature_detected!("avx2"),
                    "fma" => std::arch::is_x86_feature_detected!("fma"),
                    _ => std::arch::is_x86_feature_detected!("avx"),
                }
        };
        if has("avx512f") {
            "AVX-512F"
        } else if has("fma") && has("avx2") {
            "AVX2 + FMA"
        } else if has("avx") {
            "AVX"
        } else {
            "SSE2"
        }
    }
    #[cfg(target_arch = "aarch64")]
    {
        "NEON"
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        "portable"
    }
}

/// STREAM-like triad `a[i] = b[i] + s·c[i]` over 32 Mi f32 per array (3 × 128 MB, far beyond
/// any cache), in parallel over the rayon threads; best of 5. Bytes counted as STREAM does:
/// 12 per element (two reads, one write; the write-allocate read is not counted). Bytes/s.
pub(crate) fn triad_bandwidth() -> f64 {
    const N: usize = 32 << 20;
    let b = vec![1.0f32; N];
    let c = vec![2.0f32; N];
    let mut a = vec![0.0f32; N];
    let mut best = 0.0f64;
    for rep in 0..6 {
        let t = Instant::now();
        a.par_chunks_mut(1 << 16)
            .zip(b.par_chunks(1 << 16))
            .zip(c.par_chunks(1 << 16))
            .for_each(|((a, b), c)| {
                for ((x, y), z) in a.iter_mut().zip(b).zip(c) {
                    *x = y + 3.0 * z;
                }
            });
        let w = t.elapsed().as_secs_f64();
        black_box(&a);
        if rep > 0 {
            best = best.max(12.0 * N as f64 / w);
        }
    }
    println!(
        "== memory bandwidth (STREAM-like triad, 3 x 128 MB, best of 5): {:.1} GB/s ==",
        best / 1e9
    );
    best
}

/// FLOPs of independent FMA chains on one thread (16 AVX-512 or 12 eight-lane accumulators hide
/// the latency; the width is the build's: [`fma_isa`]).
pub(crate) fn fma_thread(iters: u64) -> f64 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    unsafe {
        use std::arch::x86_64::*;
        let mut acc = [_mm512_set1_ps(0.0); 16];
        let a = _mm512_set1_ps(0.999_999);
        let b = _mm512_set1_ps(1e-7);
        for _ in 0..iters {
            for v in acc.iter_mut() {
                *v = _mm512_fmadd_ps(*v, a, b);
            }
        }
        let mut s = 0.0;
        for v in acc {
            s += _mm512_reduce_add_ps(v);
        }
        black_box(s);
        return (iters * 16 * 16 * 2) as f64;
    }
    #[allow(unreachable_code)]
    {
        // 12 chains of 8 lanes: with the two constants that is 14 of AVX2's 16 `ymm` registers
        // (16 chains would spill and halve the figure); still more than the 2 FMA pipes × 4
        // cycles of latency a core needs in flight.
        let mut acc = [[0f32; 8]; 12];
        for _ in 0..iters {
            for v in acc.iter_mut() {
                for x in v.iter_mut() {
                    *x = x.mul_add(0.999_999, 1e-7);
                }
            }
        }
        black_box(acc);
        (iters * 12 * 8 * 2) as f64
    }
}

/// FMA peak of all threads (FLOP/s): best of three runs, per CPU second × threads (robust to
/// other load on the machine).
pub(crate) fn fma_peak() -> f64 {
    let threads = rayon::current_num_threads();
    let iters = 20_000_000u64;
    fma_thread(iters / 100); // warm up
    let mut best = (0.0f64, 0.0f64);
    for _ in 0..3 {
        let c = Clock::start();
        let flops: f64 = (0..threads)
            .into_par_iter()
            .map(|_| fma_thread(iters))
            .sum();
        let (w, cpu) = c.stop();
        best.0 = best.0.max(flops / w);
        best.1 = best.1.max(flops / cpu * threads as f64);
    }
    println!(
        "== f32 FMA peak ({threads} threads, {}, best of 3): {:.1} GFLOP/s wall, {:.1} GFLOP/s CPU-time normalised ==",
        fma_isa(),
        best.0 / 1e9,
        best.1 / 1e9
    );
    best.1
}
