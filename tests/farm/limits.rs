//! Requests whose cost would grow with what they ask for, against a coordinator under a
//! 4 GB address-space limit (standing in for the out-of-memory killer): each is refused
//! with a 4xx that says the limit, and the coordinator lives on with little memory.

use super::Farm;
use super::connections::{connect, error_of, exchange_with};
use std::io::{Read, Write};
use std::time::Duration;

#[test]
fn a_coordinator_under_4_gb_refuses_requests_that_would_grow_it_and_lives_on() {
    let farm = Farm::process_under("ulimit -v 4000000");

    // Five entries 32,700 folders deep (a 327 KB bundle): once, memory in the square of
    // the depth.
    let deep = "a/".repeat(32_700) + "f";
    let mut files = vec![("scene.pbrt".to_string(), b"WorldBegin\n".to_vec())];
    files.extend((0..5).map(|i| (format!("{deep}{i}"), Vec::new())));
    let bundle = kiln_farm::bundle::encode(&files).bytes;
    let head = format!(
        "POST /v1/scenes HTTP/1.1\r\nhost: kiln\r\ncontent-length: {}\r\nconnection: close\r\n\r\n",
        bundle.len()
    );
    let (status, headers, body) = exchange_with(&farm.url, move |w| {
        let _ = w
            .write_all(head.as_bytes())
            .and_then(|()| w.write_all(&bundle));
    });
    assert_eq!(status, 400, "{body}");
    assert!(
        error_of(&headers, &body).contains("the most is 4096"),
        "{body}"
    );

    // Tiles of one pixel on an 8192 x 8192 frame: once, 3.7 GB of tile records.
    let digest = farm.upload(&crate::util::scene("furnace/scene.pbrt"));
    let spec = kiln_farm::api::JobSpec {
        resolution: Some((8192, 8192)),
        tile: 1,
        ..Farm::spec(&digest)
    };
    let refused = farm.rt.block_on(farm.client.create_job(&spec, None));
    let message = refused.unwrap_err().to_string();
    assert!(message.contains("tiles"), "{message}");

    // Two pre-passes of 1 GiB each, at once, under a name a job of the scene can have:
    // once, both held whole in memory.
    let spec = Farm::spec(&digest);
    farm.create(&spec);
    let prefix = kiln_farm::api::prepass_prefix(&spec.overrides());
    let sending: Vec<_> = (0..2)
        .map(|_| {
            let url = farm.url.clone();
            let head = format!(
                "PUT /v1/scenes/{digest}/prepass/{prefix}-photon-maps HTTP/1.1\r\nhost: kiln\r\n\
                 content-length: {}\r\nx-kiln-prepass-sha256: {}\r\nconnection: close\r\n\r\n",
                1u64 << 30,
                "0".repeat(64)
            );
            std::thread::spawn(move || {
                exchange_with(&url, move |w| {
                    let chunk = vec![0u8; 1 << 20];
                    if w.write_all(head.as_bytes()).is_ok() {
                        for _ in 0..1024 {
                            if w.write_all(&chunk).is_err() {
                                return;
                            }
                        }
                    }
                })
            })
        })
        .collect();
    for s in sending {
        let (status, headers, body) = s.join().unwrap();
        assert_eq!(status, 413, "{body}");
        assert!(error_of(&headers, &body).contains("536870912"), "{body}");
    }

    // A 128 MiB bundle downloaded by six clients at once: once, six copies in memory. Now
    // the coordinator holds less than one (it peaked at 22 MiB here).
    let mut noise = vec![0u8; 128 << 20];
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    for b in noise.iter_mut() {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        *b = x as u8;
    }
    let big = kiln_farm::bundle::encode(&[
        ("scene.pbrt".to_string(), b"WorldBegin\n".to_vec()),
        ("noise.bin".to_string(), noise),
    ]);
    let digest = farm
        .rt
        .block_on(farm.client.upload_scene(big.bytes))
        .unwrap();
    assert_eq!(digest, big.digest);
    let downloads: Vec<_> = (0..6)
        .map(|_| {
            let request = format!(
                "GET /v1/scenes/{digest} HTTP/1.1\r\nhost: kiln\r\nconnection: close\r\n\r\n"
            );
            let mut stream = connect(&farm.url, Duration::from_secs(30));
            std::thread::spawn(move || {
                stream.write_all(request.as_bytes()).unwrap();
                // Read slowly, as a worker on a thin link would: the server must not hold
                // what the client has not taken yet.
                let (mut total, mut buf) = (0usize, vec![0u8; 1 << 20]);
                loop {
                    let n = stream.read(&mut buf).unwrap();
                    if n == 0 {
                        break total;
                    }
                    total += n;
                    std::thread::sleep(Duration::from_micros(200));
                }
            })
        })
        .collect();
    for d in downloads {
        assert!(d.join().unwrap() > 128 << 20);
    }

    let health = farm
        .rt
        .block_on(reqwest::get(format!("{}/healthz", farm.url)));
    assert_eq!(health.unwrap().status(), 200);
    let status =
        std::fs::read_to_string(format!("/proc/{}/status", farm.coordinator_pid())).unwrap();
    let peak_kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .unwrap();
    eprintln!("the coordinator peaked at {} MiB", peak_kb >> 10);
    assert!(peak_kb < 96 << 10, "the coordinator peaked at {peak_kb} kB");
}
