import json
floors={'blob':0.240,'torus':0.304,'thin':0.293,'blocks':0.253,'relief':0.169,'double-torus':0.272,'plate':0.218,'rods':0.266,'cup':0.231}
fast0={'blob':(.659,0),'torus':(.374,1),'thin':(.436,0),'blocks':(.890,2),'relief':(.630,0),'double-torus':(.467,2),'plate':(.364,0),'rods':(.391,5),'cup':(4.812,2)}
def run(sc,tag,s):
    p={('cup','w5'):{0:'r/v1w5',1:'r/v1w5_s1'},('cup','w10'):{0:'r/v1w10',1:'r/v1w10_s1'}}.get((sc,tag),{}).get(s, f'r/{sc}_v1{tag}_s{s}')
    m=json.load(open(p+'/metrics.json')); return m['chamfer']['chamfer_sum'],m['mesh']['largest_genus'],m['gt_genus'],m['normal_error_deg']
cols=[('fast',0),('w5',0),('w10',0),('w5',1),('w10',1)]
sums={c:[] for c in cols}
print('| scene | floor | `fast` s0 (*cited*) | w5 s0 (*cited*) | **w10 s0** | w5 s1 (*cited*) | **w10 s1** |'); print('|---|---|---|---|---|---|---|')
for sc,f in floors.items():
    cells=[]
    for c in cols:
        if c[0]=='fast': v,g=fast0[sc]; gt=0 if sc not in('torus','double-torus','rods') else {'torus':1,'double-torus':2,'rods':5}[sc]
        else: v,g,gt,_=run(sc,c[0],c[1])
        sums[c].append((sc,v/f)); cells.append(f'{v:.3f} ({v/f:.2f}×, {g}/{gt})')
    print(f'| {sc} | {f:.3f} | '+' | '.join(cells)+' |')
print('| **mean ratio** (without cup) | | '+' | '.join(f"**{sum(r for _,r in sums[c])/9:.2f}×** ({sum(r for s,r in sums[c] if s!='cup')/8:.2f}×)" for c in cols)+' |')
for c in cols[1:]:
    print(c, 'nerr', {sc:round(run(sc,c[0],c[1])[3],1) for sc in floors})
