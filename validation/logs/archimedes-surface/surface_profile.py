import numpy as np, sys
f = open(sys.argv[1],'rb').read()
h = f.index(b'end_header\n')+len(b'end_header\n')
dt = np.dtype([('x','<f4'),('y','<f4'),('z','<f4'),('vx','<f4'),('vy','<f4'),('vz','<f4'),('m','<i4'),('p','<f4')])
a = np.frombuffer(f[h:], dtype=dt)
dx = float(sys.argv[2]); cx=cz=0.3; half=0.06
far = np.maximum(np.abs(a['x']-cx)-half, np.abs(a['z']-cz)-half) > 0.1
y = a['y'][far]; x=a['x'][far]; z=a['z'][far]
print("n far", far.sum(), "98th", np.sort(y)[::-1][len(y)//50]+dx/4)
for b in [dx, dx/2]:
    ix = np.floor(x/b).astype(int); iz=np.floor(z/b).astype(int)
    key = ix*100000+iz
    order = np.lexsort((y, key))
    k = key[order]; yy=y[order]
    last = np.r_[k[1:]!=k[:-1], True]
    tops = yy[last]; kk = k[last]
    print(f"bin {b}: columns {len(tops)}, median top+dx/4 {np.median(tops)+dx/4:.5f}, mean {tops.mean()+dx/4:.5f}, p10 {np.percentile(tops,10)+dx/4:.5f} p90 {np.percentile(tops,90)+dx/4:.5f}")
    # by distance to wall
    cxs = (kk//100000 + 0.5)*b; czs = (kk%100000+0.5)*b
    dw = np.minimum(np.minimum(cxs-0.06, 0.54-cxs), np.minimum(czs-0.06, 0.54-czs))
    for lo,hi in [(0,dx),(dx,2*dx),(2*dx,3*dx),(3*dx,1)]:
        s = (dw>=lo)&(dw<hi)
        if s.sum(): print(f"   wall dist [{lo:.3f},{hi:.3f}): n {s.sum()} median {np.median(tops[s])+dx/4:.5f}")
# volume-based: total particle count per area
b = dx
ix = np.floor(x/b).astype(int); iz=np.floor(z/b).astype(int)
key = ix*100000+iz
order = np.lexsort((y, key)); k = key[order]; yy=y[order]
last = np.r_[k[1:]!=k[:-1], True]; tops = yy[last]; kk=k[last]
cxs = (kk//100000 + 0.5)*b; czs = (kk%100000+0.5)*b
dw = np.minimum(np.minimum(cxs-0.06, 0.54-cxs), np.minimum(czs-0.06, 0.54-czs))
for w in [0.02, 0.04]:
    s = dw >= w
    print(f"columns >= {w} m from walls: n {s.sum()} median {np.median(tops[s])+dx/4:.5f}")
# near the box too: columns 0.03..0.1 from box
alln = np.maximum(np.abs(a['x']-cx)-half, np.abs(a['z']-cz)-half)
for lo in [0.02, 0.04]:
    sel = (alln > lo)
    X=a['x'][sel]; Y=a['y'][sel]; Z=a['z'][sel]
    ix = np.floor(X/b).astype(int); iz=np.floor(Z/b).astype(int); key=ix*100000+iz
    order=np.lexsort((Y,key)); k=key[order]; yy=Y[order]; last=np.r_[k[1:]!=k[:-1],True]; t=yy[last]; kk=k[last]
    cxs=(kk//100000+0.5)*b; czs=(kk%100000+0.5)*b
    dw=np.minimum(np.minimum(cxs-0.06,0.54-cxs),np.minimum(czs-0.06,0.54-czs))
    s = dw >= 0.04
    print(f"columns > {lo} m from box and >= 0.04 from walls: n {s.sum()} median {np.median(t[s])+dx/4:.5f}")
