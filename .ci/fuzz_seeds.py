#!/usr/bin/env python3
"""Writes protobuf text-format seeds for the fuzz targets that take serialized messages
(.ci/fuzz encodes them with protoc --encode): a valid SubmitJobRequest (the cornell-box bundle at
32x32), and WorkerMessages a registered worker could send (a tile result of the right size under
the current lease, a batch of plausible records, a tile failure). Usage: fuzz_seeds.py DATA OUT."""
import os
import sys


def text_bytes(data: bytes) -> str:
    out = []
    for b in data:
        c = chr(b)
        if c in '\\"':
            out.append('\\' + c)
        elif 32 <= b < 127:
            out.append(c)
        else:
            out.append('\\%03o' % b)
    return '"' + ''.join(out) + '"'


def main() -> None:
    data, out = sys.argv[1], sys.argv[2]
    scene = os.path.join(data, 'scenes', 'cornell-box')
    files = ''.join(
        'files { path: "%s" content: %s } ' % (rel, text_bytes(open(os.path.join(scene, rel), 'rb').read()))
        for rel in ('scene.xml', 'meshes/large-box.obj'))
    os.makedirs(os.path.join(out, 'submit_request_fuzz'), exist_ok=True)
    os.makedirs(os.path.join(out, 'worker_message_fuzz'), exist_ok=True)
    with open(os.path.join(out, 'submit_request_fuzz', 'cornell.txt'), 'w') as f:
        f.write('scene { bundle { main_file: "scene.xml" %s } } settings { tile_size: 16 '
                'defines { key: "resx" value: "32" } defines { key: "resy" value: "32" } } '
                'name: "seed"\n' % files)
    msgs = {
        'result.txt': 'tile_result { %s stats { wall_seconds: 0.01 } }' % ' '.join(['pixels: 0.5'] * 768),
        'records.txt': 'records { batch { values: [0, 0, 0, 0, 1, 0, 0.5, 0.5, 0.5, 0.1] origins: 0 } }',
        'failed.txt': 'tile_failed { reason: "cannot open scene" }',
    }
    for name, text in msgs.items():
        with open(os.path.join(out, 'worker_message_fuzz', name), 'w') as f:
            f.write(text + '\n')


main()
