"""Draws the error-map distribution in use (checkpoint tensor error_map.cdf) of 12 training views
as one PNG. Usage: emview.py CHECKPOINT OUT.png [CELLS_X CELLS_Y] (numpy, matplotlib; cells
default 50 x 38: 400 x 300 views, cells of 8 px)."""
import json, struct, sys, numpy as np
import matplotlib; matplotlib.use('Agg'); import matplotlib.pyplot as plt
ck, out = sys.argv[1], sys.argv[2]
cw, ch = (int(sys.argv[3]), int(sys.argv[4])) if len(sys.argv) > 4 else (50, 38)
b = open(ck, 'rb').read(); n = struct.unpack('<Q', b[:8])[0]; h = json.loads(b[8:8 + n])
s, e = h['error_map.cdf']['data_offsets']
cdf = np.frombuffer(b[8 + n + s:8 + n + e], dtype='<f4').astype(np.float64)
per = cw * ch; nv = len(cdf) // per
fig, ax = plt.subplots(3, 4, figsize=(16, 9))
for i, a in enumerate(ax.flat):
    v = i * nv // 12
    c = cdf[v * per:(v + 1) * per]; p = np.diff(np.concatenate([[0.0], c])) / c[-1]
    top = np.sort(p)[::-1][:per // 10].sum()
    a.imshow(p.reshape(ch, cw), cmap='magma')
    a.set_title(f'view {v}: top tenth of cells {top:.2f}, max cell {p.max():.3f}'); a.axis('off')
plt.tight_layout(); plt.savefig(out, dpi=60)
