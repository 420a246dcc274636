import numpy as np,sys
d=sys.argv[1]; s=float(open(d+'/scale.txt').read())
bins=[-1e9,-50,-20,-10,-5,-3,-2,2,3,5,10,20,50,1e9]
for src in [1,2]:
  for part in [1,2]:
    es=[]
    for v in range(46):
        t=np.fromfile(f'{d}/t{v:02}.f32',np.float32); g=np.fromfile(f'{d}/g{v:02}.f32',np.float32)
        f=np.fromfile(f'{d}/f{v:02}.u8',np.uint8); p=np.fromfile(f'{d}/p{v:02}.u8',np.uint8)
        m=np.isfinite(t)&np.isfinite(g)&(f==src)&(p==part)
        es.append(((t-g)*s)[m])
    e=np.concatenate(es); h,_=np.histogram(e,bins)
    print(src,part,len(e),' '.join('%s:%.3f'%(b,c/len(e)) for b,c in zip(bins[1:],h)))
