"""Each rod's fused position from a rodtrack fusion node (binary layout v1, docs/network.md).
Usage: python zenoh_subscriber.py [ENDPOINT [SECONDS]], e.g. tcp/127.0.0.1:7447 10."""
import json, struct, sys, time
import zenoh  # pip install eclipse-zenoh

def on_rows(sample):
    b = sample.payload.to_bytes()
    magic, version, kind, flags, n, _, seq, frame, t_ns, cams = struct.unpack_from("<4sHBBHHIQQQ", b)
    assert magic == b"RTZN" and version == 1, "not binary layout v1"
    for k in range(n):
        _, rod, pos_mm, _, turn_rad, _, _, _, status = struct.unpack_from("<IIddddddB", b, 40 + 64 * k)
        print(f"frame {frame} t_ns {t_ns} rod {rod} position_mm {pos_mm:.4f} turn_rad {turn_rad:.5f} status {status}", flush=True)

conf = zenoh.Config()
if len(sys.argv) > 1:  # an explicit endpoint, no multicast discovery
    conf.insert_json5("connect/endpoints", json.dumps([sys.argv[1]]))
    conf.insert_json5("scouting/multicast/enabled", "false")
with zenoh.open(conf) as session:
    sub = session.declare_subscriber("rodtrack/*/fused/rows", on_rows)
    time.sleep(float(sys.argv[2]) if len(sys.argv) > 2 else 1e9)
