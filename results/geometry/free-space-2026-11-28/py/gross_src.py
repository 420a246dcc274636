import numpy as np,sys
d=sys.argv[1]; s=float(open(d+'/scale.txt').read()); agg={}
for v in range(46):
    t=np.fromfile(f'{d}/t{v:02}.f32',np.float32); g=np.fromfile(f'{d}/g{v:02}.f32',np.float32)
    p=np.fromfile(f'{d}/p{v:02}.u8',np.uint8); f=np.fromfile(f'{d}/f{v:02}.u8',np.uint8)
    e=(t-g)*s; ok=np.isfinite(e)
    for part in range(4):
      for src in range(3):
        m=ok&(p==part)&(f==src); a=agg.setdefault((part,src),np.zeros(3)); a+=[m.sum(),(e[m]<-10).sum(),(e[m]>10).sum()]
for (part,src),a in sorted(agg.items()): print(['bot','in','out','oth'][part], ['stereo','fused','hole'][src], 'n %d F10 %d B10 %d'%tuple(a))
