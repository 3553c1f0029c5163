//! Golden byte snapshots of every link message, framed as on the wire (postcard, CRC-32,
//! COBS, zero delimiter). If one of these changes, the bytes on the wire changed: bump
//! `wire::PROTOCOL_VERSION` and update the snapshot (the failure prints the new bytes).

use dollop::executor::{Fault, RunState};
use dollop::job::{JobHeader, FORMAT_VERSION};
use dollop::wire::*;
use dollop::{Axis, Config};

const CONFIG: &str = r#"
[channel]
nozzle_diameter_mm = 0.8
channel_length_mm = 2.4
nozzle_height_mm = 0.8
layer_height_mm = 0.6
line_pitch_mm = 0.8

[motion]
steps_per_mm = [80.0, 80.0, 400.0]
travel_min_mm = [0.0, 0.0, 0.0]
travel_max_mm = [200.0, 200.0, 100.0]
max_speed_mm_s = [150.0, 150.0, 20.0]
max_accel_mm_s2 = [2000.0, 2000.0, 200.0]
print_speed_mm_s = 10.0
print_speed_max_mm_s = 30.0
travel_speed_mm_s = 80.0
max_step_rate_hz = 50000.0

[[inlet]]
material = "A"
rheology = { newtonian = { viscosity_pa_s = 1.41 } }
pressure_kpa = 200.0
"#;

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn host(seq: u16, r: &Request<'_>) -> String {
    let mut buf = [0u8; MAX_FRAME + 1];
    let n = encode(
        &HostHeader {
            session: 0x1234,
            seq,
        },
        r,
        &mut buf,
    )
    .unwrap();
    hex(&buf[..n])
}

fn device(r: &Reply) -> String {
    let mut buf = [0u8; MAX_FRAME + 1];
    let h = DeviceHeader {
        session: 0x1234,
        answers: 7,
        next: 8,
        credit: 3,
    };
    let n = encode(&h, r, &mut buf).unwrap();
    hex(&buf[..n])
}

fn id() -> JobId {
    JobId {
        body_crc: 0xDEAD_BEEF,
        body_len: 1000,
        config_hash: 0x0102_0304,
    }
}

fn header() -> JobHeader {
    JobHeader {
        format_version: FORMAT_VERSION,
        config_hash: 0x0102_0304,
        materials: heapless::Vec::new(),
        bounds_min_um: [1000, 2000, 600],
        bounds_max_um: [3000, 4000, 1200],
        start_um: [1000, 2000, 600],
        initial_material: 1,
        print_segments: 10,
        commands: 12,
        body_len: 1000,
        body_crc: 0xDEAD_BEEF,
    }
}

fn snapshot() -> Snapshot {
    Snapshot {
        mode: Mode::Job,
        run: RunState::Printing,
        halt: None,
        homed: true,
        estop: false,
        drivers: true,
        valves: 0b10,
        position_um: [12_345, -6, 600],
        command: 77,
        epoch: 2,
        speed_mm_s: 10.5,
        q_mm3_s: 5.0,
        pause_point_um: Some([12_345, -6_789, 600]),
    }
}

fn messages() -> Vec<(&'static str, String)> {
    let config: Config = toml::from_str(CONFIG).unwrap();
    let data = [1u8, 2, 0, 0xFF];
    let mut v = vec![
        (
            "hello",
            host(
                1,
                &Request::Hello {
                    version: PROTOCOL_VERSION,
                },
            ),
        ),
        ("status", host(2, &Request::Status)),
        ("load_config", host(3, &Request::LoadConfig(config))),
        ("settings", host(4, &Request::Settings(Settings::default()))),
        ("begin_job", host(5, &Request::BeginJob(header()))),
        (
            "chunk",
            host(
                6,
                &Request::Chunk {
                    offset: 256,
                    data: &data,
                },
            ),
        ),
        ("end_job", host(7, &Request::EndJob)),
        ("start", host(8, &Request::Start)),
        ("pause", host(9, &Request::Pause)),
        ("resume", host(10, &Request::Resume)),
        ("park", host(9, &Request::Park)),
        ("refill", host(9, &Request::Refill)),
        ("abort", host(11, &Request::Abort)),
        ("estop", host(12, &Request::EStop)),
        ("clear_fault", host(13, &Request::ClearFault)),
        ("home", host(14, &Request::Home)),
        (
            "jog",
            host(
                15,
                &Request::Jog {
                    axis: Axis::Y,
                    um: -2500,
                },
            ),
        ),
        (
            "valve",
            host(
                16,
                &Request::Valve {
                    inlet: 1,
                    open: true,
                },
            ),
        ),
    ];
    let hello = HelloInfo {
        version: PROTOCOL_VERSION,
        firmware: "0.1.0".try_into().unwrap(),
        board: "dollop-f405".try_into().unwrap(),
        max_chunk: MAX_CHUNK as u16,
        window: WINDOW as u8,
        capacity: 768 * 1024,
        config: Some(0x0102_0304),
        job: JobSlot::Receiving {
            id: id(),
            received: 512,
        },
    };
    v.push(("reply_hello", device(&Reply::Hello(hello))));
    v.push(("reply_ack", device(&Reply::Ack)));
    for (name, job) in [
        ("reply_status_empty", JobSlot::Empty),
        ("reply_status_preparing", JobSlot::Preparing { id: id() }),
        (
            "reply_status_verifying",
            JobSlot::Verifying {
                id: id(),
                checked: 9,
            },
        ),
        (
            "reply_status_ready",
            JobSlot::Ready {
                id: id(),
                commands: 12,
                segments: 10,
            },
        ),
        (
            "reply_status_failed",
            JobSlot::Failed {
                id: id(),
                why: JobFailure::BodyCrc,
            },
        ),
    ] {
        let s = Status {
            control: snapshot(),
            job,
            fed: 80,
            config: Some(0x0102_0304),
            link_lost: false,
            line_errors: LineErrors::default(),
        };
        v.push((name, device(&Reply::Status(s))));
    }
    let mut halted = snapshot();
    halted.mode = Mode::Halted;
    halted.halt = Some(Halt::Fault(Fault::EStop));
    v.push((
        "reply_status_halted",
        device(&Reply::Status(Status {
            control: halted,
            job: JobSlot::Empty,
            fed: 0,
            config: None,
            link_lost: true,
            line_errors: LineErrors {
                overrun: 3,
                framing: 1,
                noise: 0,
                parity: 300,
            },
        })),
    ));
    let refusals: Vec<(&'static str, Refusal)> = vec![
        ("refused_version", Refusal::Version { device: 1, host: 2 }),
        ("refused_no_session", Refusal::NoSession),
        ("refused_busy", Refusal::Busy { mode: Mode::Homing }),
        ("refused_queue_full", Refusal::QueueFull),
        ("refused_no_config", Refusal::NoConfig),
        (
            "refused_config",
            Refusal::Config(text(format_args!("channel.nozzle_diameter_mm: invalid"))),
        ),
        (
            "refused_settings",
            Refusal::Settings(text(format_args!("settings.home_speed_mm_s"))),
        ),
        (
            "refused_config_mismatch",
            Refusal::ConfigMismatch { job: 1, device: 2 },
        ),
        (
            "refused_too_large",
            Refusal::JobTooLarge {
                len: 900_000,
                capacity: 786_432,
            },
        ),
        (
            "refused_outside",
            Refusal::JobOutsideTravel { axis: Axis::Z },
        ),
        (
            "refused_header",
            Refusal::JobHeader(text(format_args!("version"))),
        ),
        (
            "refused_job",
            Refusal::Job(JobFailure::CommandCount {
                expected: 3,
                found: 2,
            }),
        ),
        ("refused_no_job", Refusal::NoJob),
        ("refused_not_uploading", Refusal::NotUploading),
        (
            "refused_chunk_offset",
            Refusal::ChunkOffset {
                expected: 512,
                got: 768,
            },
        ),
        ("refused_chunk_size", Refusal::ChunkSize { len: 300 }),
        ("refused_not_homed", Refusal::NotHomed),
        (
            "refused_soft_limit",
            Refusal::SoftLimit {
                axis: Axis::X,
                target_um: -1,
                min_um: 0,
                max_um: 200_000,
            },
        ),
        (
            "refused_no_inlet",
            Refusal::NoSuchInlet {
                inlet: 5,
                inlets: 2,
            },
        ),
        (
            "refused_halted",
            Refusal::Halted(Halt::HomingFailed { axis: Axis::Z }),
        ),
        ("refused_estop", Refusal::EStopActive),
        ("refused_store", Refusal::Store(StoreError::Erase)),
        (
            "refused_not_paused",
            Refusal::NotPaused {
                run: RunState::Printing,
            },
        ),
    ];
    for (name, r) in refusals {
        v.push((name, device(&Reply::Refused(r))));
    }
    v
}

const GOLDEN: &[(&str, &str)] = &[
    ("hello", "04b4240106032d5afe9400"),
    ("status", "09b4240201f9ba21c900"),
    ("load_config", "19b4240302cdcc4c3f9a991940cdcc4c3f9a99193fcdcc4c3f010103a0420103a0420103c84301010101010101010101010101034843010348430103c84201031643010316430103a0410103fa440103fa4401034843010320410103f0410103a0420e504347010ad7a33b904e01014105e17ab43f0103484301010101010101010101010101010101010103a040050ab67c8500"),
    ("settings", "05b42404030202020101020101032041010106401604cae900"),
    ("begin_job", "0ab4240504018486880821d00fa01fb009f02ec03ee012d00fa01fb009010a0ce807effdb6f50da3c2899200"),
    ("chunk", "0ab4240605800204010206ff16d9fd5f00"),
    ("end_job", "09b42407061fdb322a00"),
    ("start", "09b424080746f7adda00"),
    ("pause", "09b424090896db095300"),
    ("resume", "09b4240a09c3b8230f00"),
    ("refill", "09b42409115673623700"),
    ("park", "09b4240910c043654000"),
    ("abort", "09b4240b0a38d8318f00"),
    ("estop", "09b4240c0b697e77b700"),
    ("clear_fault", "09b4240d0c8bda083000"),
    ("home", "09b4240e0ddeb9226c00"),
    ("jog", "0cb4240f0e018727dfc2ee6700"),
    ("valve", "0bb424100f01017168813100"),
    ("reply_hello", "06b424070803310305302e312e300b646f6c6c6f702d66343035800208808030018486880802effdb6f50de807848688088004da82cdc900"),
    ("reply_ack", "0bb42407080301507336cb00"),
    ("reply_status_empty", "09b42407080302050102010b0102f2c0010bb0094d0201032841010ba04001f2c001896ab0090750018486880801010101054ab56aa900"),
    ("reply_status_preparing", "09b42407080302050102010b0102f2c0010bb0094d0201032841011da04001f2c001896ab00901effdb6f50de807848688085001848688080101010105297390f700"),
    ("reply_status_verifying", "09b42407080302050102010b0102f2c0010bb0094d0201032841011ea04001f2c001896ab00903effdb6f50de807848688080950018486880801010101058ad98b0e00"),
    ("reply_status_ready", "09b42407080302050102010b0102f2c0010bb0094d0201032841011fa04001f2c001896ab00904effdb6f50de807848688080c0a50018486880801010101053661773c00"),
    ("reply_status_failed", "09b42407080302050102010b0102f2c0010bb0094d0201032841011ea04001f2c001896ab00905effdb6f50de8078486880801500184868808010101010524fdbab800"),
    ("reply_status_halted", "0ab424070803020601010308010b0102f2c0010bb0094d0201032841010ba04001f2c001896ab00901010401030107ac02e16dbd1700"),
    ("refused_version", "07b4240708030307010223d0490500"),
    ("refused_no_session", "0cb42407080303011eda93fc00"),
    ("refused_busy", "0db424070803030202db73d2ed00"),
    ("refused_queue_full", "0cb424070803030332bb9d1200"),
    ("refused_no_config", "0cb4240708030304912ef98c00"),
    ("refused_config", "30b4240708030305236368616e6e656c2e6e6f7a7a6c655f6469616d657465725f6d6d3a20696e76616c696467e0a4d800"),
    ("refused_settings", "25b42407080303061873657474696e67732e686f6d655f73706565645f6d6d5f73cbc3b20500"),
    ("refused_config_mismatch", "0db42407080303070102a6c6060100"),
    ("refused_too_large", "12b4240708030308a0f73680803024adcf0700"),
    ("refused_outside", "0db42407080303090210aa260e00"),
    ("refused_header", "14b424070803030a0776657273696f6eb3e276bf00"),
    ("refused_job", "0fb424070803030b0303022dd4f05300"),
    ("refused_no_job", "0cb424070803030ca3a6228200"),
    ("refused_not_uploading", "0cb424070803030d359625f500"),
    ("refused_chunk_offset", "10b424070803030e80048006f09c1b4500"),
    ("refused_chunk_size", "0eb424070803030fac02ba55bc1500"),
    ("refused_not_homed", "0cb4240708030310ecfa239600"),
    ("refused_soft_limit", "08b424070803031102010880b5181b0d256900"),
    ("refused_no_inlet", "0eb424070803031205023962877e00"),
    ("refused_halted", "0eb424070803031301020acd291b00"),
    ("refused_estop", "0cb4240708030314f53e4e9100"),
    ("refused_store", "0db424070803031501f7a6587100"),
    ("refused_not_paused", "0db424070803031801bad8f6c400"),
];

#[test]
fn every_message_matches_its_golden_bytes() {
    let got = messages();
    let mut report = String::new();
    for (name, bytes) in &got {
        let want = GOLDEN.iter().find(|(n, _)| n == name).map(|(_, b)| *b);
        if want != Some(bytes.as_str()) {
            report.push_str(&format!("    (\"{name}\", \"{bytes}\"),\n"));
        }
    }
    assert!(
        report.is_empty() && got.len() == GOLDEN.len(),
        "wire bytes changed (bump PROTOCOL_VERSION), new snapshot lines:\n{report}"
    );
}

#[test]
fn every_golden_frame_decodes_back() {
    for (name, hexs) in GOLDEN {
        let mut bytes: Vec<u8> = (0..hexs.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&hexs[i..i + 2], 16).unwrap())
            .collect();
        assert_eq!(bytes.pop(), Some(0), "{name}: no delimiter");
        assert!(!bytes.contains(&0), "{name}: zero inside a COBS frame");
        let mut copy = bytes.clone();
        let host = decode::<HostHeader, Request<'_>>(&mut bytes).is_ok();
        let dev = decode::<DeviceHeader, Reply>(&mut copy).is_ok();
        assert!(host || dev, "{name} does not decode");
    }
}

#[test]
fn hello_version_is_readable_across_versions() {
    // A hello from version 99 with a field this version does not know still shows its
    // version, so the refusal can name both.
    let mut buf = [0u8; 64];
    let payload = postcard::to_slice(
        &(HostHeader { session: 5, seq: 9 }, 0u32, 99u16, 42u32),
        &mut buf,
    )
    .unwrap()
    .to_vec();
    assert!(parse::<HostHeader, Request<'_>>(&payload).is_err());
    let (h, v) = peek_hello::<HostHeader>(&payload).unwrap();
    assert_eq!((h.session, h.seq, v), (5, 9, 99));
}
