#pragma once
// The dashboard page: one self-contained HTML file, no external assets (a
// rig computer in the field has no network). Built for an operator with one
// glance to spare: the advice in large words at the top, a top view of the
// targets (coloured by coverage), the camera and its path and the feature
// cloud, and a gauge of the distance against the range that meets the goal.
// It draws whatever fields the status has and skips those it lacks.
namespace tagsfm {

inline constexpr const char* kDashboardPage = R"HTML(<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width">
<title>tagsfm live</title>
<style>
body{font-family:system-ui,sans-serif;margin:.8em;background:#111;color:#eee}
h1{font-size:1.1em;margin:0 0 .4em;font-weight:normal}
#advice{font-size:2.4em;font-weight:bold;line-height:1.15;margin:.1em 0 .2em;min-height:1.2em}
#advice.ok{color:#6d6}#advice.warn{color:#fc6}#advice.bad{color:#f66}
#warnings{margin:0 0 .5em;padding-left:1.2em}#warnings li{color:#fc6;margin:.1em 0;font-size:1.05em}
#state.ok{color:#6d6}#state.bad{color:#f66}
.main{display:flex;flex-wrap:wrap;gap:.8em;align-items:flex-start}
#map{background:#1a1a1a;border-radius:.4em;width:640px;height:480px;flex:none}
.side{flex:1;min-width:18em}
.grid{display:grid;grid-template-columns:repeat(auto-fit,minmax(9em,1fr));gap:.4em}
.card{background:#222;border-radius:.4em;padding:.4em}
.card b{display:block;font-size:1.5em}
#gauge{width:100%;height:90px;background:#222;border-radius:.4em;margin-bottom:.4em}
.legend span{display:inline-block;margin-right:1em}.legend i{display:inline-block;width:.8em;height:.8em;margin-right:.3em}
table{border-collapse:collapse;margin-top:.8em}td,th{padding:.15em .5em;border-bottom:1px solid #333;text-align:right}
</style></head><body>
<h1>tagsfm live &mdash; <span id="state">waiting for frames</span> &middot; frame <span id="frame">-</span> &middot; <span id="fps">-</span> frames/s</h1>
<div id="advice" class="warn">Waiting for the first frame</div>
<ul id="warnings"></ul>
<div class="main">
<svg id="map" viewBox="0 0 640 480" role="img" aria-label="top view of the targets and the camera"></svg>
<div class="side">
<svg id="gauge" viewBox="0 0 400 90" role="img" aria-label="distance gauge"></svg>
<div class="grid">
<div class="card">targets in view<b id="inview">-</b></div>
<div class="card">targets mapped / seen<b id="mapped">-</b></div>
<div class="card">distance<b id="depth">-</b></div>
<div class="card">point error here<b id="perr">-</b></div>
<div class="card">camera position error<b id="cerr">-</b></div>
<div class="card">corner noise<b id="noise">-</b></div>
<div class="card" id="featcard" hidden>feature points<b id="features">-</b></div>
</div>
<p class="legend"><span><i style="background:#e44"></i>seen too few times</span><span><i style="background:#fa3"></i>one direction only</span><span><i style="background:#4c4"></i>covered</span><span><i style="background:#4af"></i>camera</span></p>
</div></div>
<table><thead><tr><th>target</th><th>times seen</th><th>direction spread</th><th>sectors</th><th>tilt</th></tr></thead>
<tbody id="coverage"></tbody></table>
<script>
const $=id=>document.getElementById(id);
const NS='http://www.w3.org/2000/svg';
const mm=v=>v==null?'-':(v*1000).toFixed(v<0.01?2:1)+' mm';
const num=v=>typeof v==='number'&&isFinite(v);
function el(parent,name,attrs,text){const e=document.createElementNS(NS,name);
  for(const k in attrs)e.setAttribute(k,attrs[k]);if(text!=null)e.textContent=text;parent.appendChild(e);return e;}
function coverageColour(c,g){
  if(!c)return '#888';
  if(c.times_seen<(g.min_views_per_target||3))return '#e44';
  if(c.direction_spread_deg<(g.min_direction_spread_deg||20))return '#fa3';
  return '#4c4';}
function drawMap(s){
  const svg=$('map');svg.textContent='';
  const m=s.map;if(!m||!m.top_x){el(svg,'text',{x:320,y:240,fill:'#888','text-anchor':'middle'},'no map yet');return;}
  const dot=(p,a)=>p[0]*a[0]+p[1]*a[1]+p[2]*a[2];
  const top=p=>[dot(p,m.top_x),dot(p,m.top_y)];
  const cloud=Array.isArray(s.cloud)?s.cloud.map(top):[];
  const targets=(m.targets||[]).map(t=>({id:t.id,p:top(t.xyz)}));
  const path=(m.path||[]).map(top);
  const cam=m.camera?top(m.camera):null;
  const pts=[...targets.map(t=>t.p),...path,...(cam?[cam]:[])];
  for(let i=0;i<cloud.length;i+=7)pts.push(cloud[i]);  // a sample is enough for the extent
  if(!pts.length){el(svg,'text',{x:320,y:240,fill:'#888','text-anchor':'middle'},'no registered frame yet');return;}
  let x0=Infinity,x1=-Infinity,y0=Infinity,y1=-Infinity;
  for(const p of pts){x0=Math.min(x0,p[0]);x1=Math.max(x1,p[0]);y0=Math.min(y0,p[1]);y1=Math.max(y1,p[1]);}
  const span=Math.max(x1-x0,y1-y0,0.2),k=Math.min(600/span,440/span);
  const cx=(x0+x1)/2,cy=(y0+y1)/2;
  const X=p=>(320+(p[0]-cx)*k).toFixed(1),Y=p=>(240-(p[1]-cy)*k).toFixed(1);
  const metres=Math.pow(10,Math.floor(Math.log10(span/2)));  // a scale bar of 1, 10 or 100 cm...
  el(svg,'line',{x1:20,y1:465,x2:20+metres*k,y2:465,stroke:'#aaa','stroke-width':2});
  el(svg,'text',{x:24+metres*k,y:469,fill:'#aaa','font-size':12},metres>=1?metres+' m':(metres*100).toFixed(0)+' cm');
  if(cloud.length){let d='';for(const p of cloud)d+='M'+X(p)+' '+Y(p)+'h0';
    el(svg,'path',{d:d,stroke:'#999','stroke-width':2,'stroke-linecap':'round','stroke-opacity':0.6});}
  if(path.length>1)el(svg,'polyline',{points:path.map(p=>X(p)+','+Y(p)).join(' '),fill:'none',stroke:'#4af','stroke-width':1.5,'stroke-opacity':0.7});
  const byId={};for(const c of s.coverage||[])byId[c.id]=c;
  const g=s.goals||{};
  for(const t of targets){
    el(svg,'rect',{x:X(t.p)-6,y:Y(t.p)-6,width:12,height:12,fill:coverageColour(byId[t.id],g),stroke:'#000'});
    el(svg,'text',{x:+X(t.p)+8,y:+Y(t.p)-8,fill:'#ccc','font-size':11},t.id);}
  if(cam&&m.camera_axis){
    const a=[dot(m.camera_axis,m.top_x),dot(m.camera_axis,m.top_y)],n=Math.hypot(a[0],a[1])||1;
    const ux=a[0]/n,uy=-a[1]/n,px=+X(cam),py=+Y(cam);
    el(svg,'polygon',{points:[px,py,px+60*ux-22*uy,py+60*uy+22*ux,px+60*ux+22*uy,py+60*uy-22*ux].join(' '),fill:'#4af','fill-opacity':0.3,stroke:'#4af'});
    el(svg,'circle',{cx:px,cy:py,r:7,fill:'#4af'});}
  const box=svg.getBoundingClientRect();
  svg.setAttribute('data-box',[box.left,box.top,box.width,box.height].map(Math.round).join(','));
}
function drawGauge(s){
  const svg=$('gauge');svg.textContent='';
  const d=s.depth_m,lim=s.max_depth_for_goal_m;
  if(!num(d)||d<=0){el(svg,'text',{x:200,y:50,fill:'#888','text-anchor':'middle','font-size':16},'no distance: no targets in view');return;}
  const top=Math.max(num(lim)?lim*1.6:0,d*1.25,0.5),x=v=>20+360*Math.min(v,top)/top;
  el(svg,'rect',{x:20,y:30,width:360,height:22,fill:'#633'});
  if(num(lim))el(svg,'rect',{x:20,y:30,width:x(lim)-20,height:22,fill:'#363'});
  el(svg,'polygon',{points:[x(d),28,x(d)-8,14,x(d)+8,14].join(' '),fill:'#fff'});
  el(svg,'line',{x1:x(d),y1:26,x2:x(d),y2:56,stroke:'#fff','stroke-width':3});
  const ok=num(lim)&&d<=lim;
  el(svg,'text',{x:20,y:76,fill:ok?'#6d6':'#fc6','font-size':16},d.toFixed(2)+' m'+(num(lim)?(ok?' \u2014 within ':' \u2014 closer than ')+lim.toFixed(2)+' m for '+mm(s.goals&&s.goals.point_error_m):''));
  el(svg,'text',{x:380,y:22,fill:'#aaa','font-size':12,'text-anchor':'end'},'point error '+mm(s.predicted_point_error_m));
}
function show(s){
  $('state').textContent=s.registered?'tracking':'no pose';
  $('state').className=s.registered?'ok':'bad';
  $('frame').textContent=s.frame;
  $('fps').textContent=num(s.frames_per_second)?s.frames_per_second.toFixed(1):'-';
  $('inview').textContent=s.targets_in_view;
  $('mapped').textContent=s.targets_mapped+' / '+s.targets_seen_total;
  $('depth').textContent=s.depth_m?s.depth_m.toFixed(2)+' m':'-';
  $('noise').textContent=num(s.image_noise_px)?s.image_noise_px.toFixed(2)+' px':'-';
  $('perr').textContent=mm(s.predicted_point_error_m);
  $('cerr').textContent=mm(s.predicted_position_error_m);
  if(num(s.feature_points)){$('featcard').hidden=false;
    $('features').textContent=s.feature_points+(num(s.feature_keyframes)?' ('+s.feature_keyframes+' keyframes)':'')+
      (s.feature_work_dropped?' \u2014 '+s.feature_work_dropped+' dropped':'');}
  const w=s.warnings||[];
  $('advice').textContent=w.length?w[0]:'Good \u2014 keep going';
  $('advice').className=w.length?(s.registered?'warn':'bad'):'ok';
  $('warnings').textContent='';
  for(const t of w.slice(1)){const li=document.createElement('li');li.textContent=t;$('warnings').appendChild(li);}
  $('coverage').textContent='';
  for(const c of s.coverage||[]){const tr=document.createElement('tr');
    for(const v of [c.id,c.times_seen,c.direction_spread_deg.toFixed(0)+'\u00b0',c.sectors_covered+'/8',
      c.min_tilt_deg.toFixed(0)+'\u2013'+c.max_tilt_deg.toFixed(0)+'\u00b0']){
      const td=document.createElement('td');td.textContent=v;tr.appendChild(td);}
    $('coverage').appendChild(tr);}
  drawMap(s);drawGauge(s);
}
// Draw at most 20 times a second: a status arriving sooner replaces the one
// waiting, so a slow tablet shows the latest state rather than falling behind.
// Counted for tests and for anyone asking how lively the page is.
let pending=null;
window.dashboardCounts={events:0,draws:0};
function queue(s){if(!pending)setTimeout(()=>{const p=pending;pending=null;dashboardCounts.draws++;show(p);},50);pending=s;}
const events=new EventSource('/events');
events.onmessage=e=>{dashboardCounts.events++;queue(JSON.parse(e.data));};
fetch('/status').then(r=>r.json()).then(s=>{if(s.frame!==undefined)queue(s);}).catch(()=>{});
</script></body></html>
)HTML";

}  // namespace tagsfm
