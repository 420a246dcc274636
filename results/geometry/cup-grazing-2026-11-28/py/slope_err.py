import numpy as np,sys
d=sys.argv[1]; s=float(open(d+'/scale.txt').read())
import glob
W=400;H=300
acc={}
for v in range(46):
    t=np.fromfile(f'{d}/t{v:02}.f32',np.float32).reshape(H,W); g=np.fromfile(f'{d}/g{v:02}.f32',np.float32).reshape(H,W)
    f=np.fromfile(f'{d}/f{v:02}.u8',np.uint8).reshape(H,W); p=np.fromfile(f'{d}/p{v:02}.u8',np.uint8).reshape(H,W)
    # truth slope mm/px: min one-sided differences
    gx=np.minimum(np.abs(np.diff(g,axis=1,append=np.nan)),np.abs(np.diff(g,axis=1,prepend=np.nan)))
    gy=np.minimum(np.abs(np.diff(g,axis=0,append=np.nan)),np.abs(np.diff(g,axis=0,prepend=np.nan)))
    sl=np.sqrt(np.nan_to_num(gx,nan=1e9)**2+np.nan_to_num(gy,nan=1e9)**2)*s
    ok=np.isfinite(t)&np.isfinite(g)&(p==2)
    e=(t-g)*s
    for src,name in [(0,'stereo'),(1,'fused'),(2,'hole')]:
        for lo,hi in [(0,0.5),(0.5,1),(1,2),(2,4),(4,1e10)]:
            m=ok&(f==src)&(sl>=lo)&(sl<hi)
            a=acc.setdefault((name,lo),[0,0,0,0])
            a[0]+=m.sum(); a[1]+=(np.abs(e[m])<2).sum(); a[2]+=(e[m]<=-2).sum(); a[3]+=(e[m]>=2).sum()
for k,a in sorted(acc.items()):
    n=max(a[0],1); print('outer %-7s slope>=%-4s mm/px n %7d good %.3f front %.3f behind %.3f'%(k[0],k[1],a[0],a[1]/n,a[2]/n,a[3]/n))
