import numpy as np,sys,glob
d=sys.argv[1]; s=float(open(d+'/scale.txt').read())
tot={}
for v in range(46):
    t=np.fromfile(f'{d}/t{v:02}.f32',np.float32); g=np.fromfile(f'{d}/g{v:02}.f32',np.float32)
    f=np.fromfile(f'{d}/f{v:02}.u8',np.uint8); p=np.fromfile(f'{d}/p{v:02}.u8',np.uint8)
    ok=np.isfinite(t)&np.isfinite(g)
    e=(t-g)*s
    for src,name in [(0,'stereo'),(1,'fused'),(2,'hole')]:
        for part,pn in [(0,'bottom'),(1,'inner'),(2,'outer'),(3,'other')]:
            m=ok&(f==src)&(p==part)
            k=(name,pn); a=tot.setdefault(k,[0,0,0,0])
            a[0]+=m.sum(); a[1]+=(np.abs(e[m])<2).sum(); a[2]+=(e[m]<=-2).sum(); a[3]+=(e[m]>=2).sum()
for k,a in sorted(tot.items()):
    n=max(a[0],1); print('%-7s %-7s n %7d  good %.3f front %.3f behind %.3f  bad %6d'%(k[0],k[1],a[0],a[1]/n,a[2]/n,a[3]/n,a[2]+a[3]))
