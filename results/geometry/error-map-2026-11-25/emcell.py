"""For five training views, the cell with the highest error in a run's error map (checkpoint
tensor error_map.err), with the mask and image content of its 8x8 pixels. Usage: emcell.py
CHECKPOINT SCENE_FOLDER (numpy, Pillow; 49 views at 400 x 300, held-out views 8, 24, 40)."""
import json, struct, sys, numpy as np
from PIL import Image
ck, scene = sys.argv[1], sys.argv[2]
b = open(ck, 'rb').read(); n = struct.unpack('<Q', b[:8])[0]; h = json.loads(b[8:8+n]); base = 8+n
s, e = h['error_map.err']['data_offsets']; err = np.frombuffer(b[base+s:base+e], dtype='<f4')
cw, ch = 50, 38; per = cw*ch; nv = len(err)//per
held = [8, 24, 40]; train = [i for i in range(nv+3) if i not in held]
print('global err quantiles', np.quantile(err, [0.5, 0.9, 0.99, 0.999]).round(4), 'max', err.max())
for v in [3, 7, 15, 23, 42]:
    m = err[v*per:(v+1)*per]; c = int(m.argmax()); cy, cx = divmod(c, cw)
    sv = train[v]
    img = np.asarray(Image.open(f'{scene}/image/{sv:06d}.png').convert('RGB')).astype(float)/255
    msk = np.asarray(Image.open(f'{scene}/mask/{sv:03d}.png').convert('L')).astype(float)/255
    blk = img[cy*8:cy*8+8, cx*8:cx*8+8]; mb = msk[cy*8:cy*8+8, cx*8:cx*8+8]
    print(f'view {v} (scene {sv}) cell ({cx},{cy}) err {m[c]:.3f}, 2nd {np.sort(m)[-2]:.3f}; mask mean {mb.mean():.2f}; img mean {blk.reshape(-1,3).mean(0).round(2)} max-min {(blk.max((0,1))-blk.min((0,1))).round(2)}')
