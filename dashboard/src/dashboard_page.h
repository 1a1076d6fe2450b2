#pragma once
// The dashboard page: one self-contained HTML file, no external assets (a
// rig computer in the field has no network).
namespace tagsfm {

inline constexpr const char* kDashboardPage = R"HTML(<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width">
<title>tagsfm live</title>
<style>
body{font-family:system-ui,sans-serif;margin:1em;background:#111;color:#eee}
h1{font-size:1.2em;margin:0 0 .5em}
.grid{display:grid;grid-template-columns:repeat(auto-fit,minmax(11em,1fr));gap:.5em}
.card{background:#222;border-radius:.4em;padding:.5em}
.card b{display:block;font-size:1.6em}
#warnings li{color:#fc6;margin:.2em 0;font-size:1.1em}
#state.ok{color:#6d6}#state.bad{color:#f66}
table{border-collapse:collapse;margin-top:1em}td,th{padding:.2em .6em;border-bottom:1px solid #333;text-align:right}
</style></head><body>
<h1>tagsfm live &mdash; <span id="state">waiting for frames</span></h1>
<ul id="warnings"></ul>
<div class="grid">
<div class="card">frame<b id="frame">-</b></div>
<div class="card">frames/s<b id="fps">-</b></div>
<div class="card">targets in view<b id="inview">-</b></div>
<div class="card">targets mapped / seen<b id="mapped">-</b></div>
<div class="card">distance<b id="depth">-</b></div>
<div class="card">corner noise<b id="noise">-</b></div>
<div class="card">point error here<b id="perr">-</b></div>
<div class="card">camera position error<b id="cerr">-</b></div>
</div>
<table><thead><tr><th>target</th><th>times seen</th><th>direction spread</th><th>sectors</th><th>tilt</th></tr></thead>
<tbody id="coverage"></tbody></table>
<script>
const $=id=>document.getElementById(id);
const mm=v=>v==null?'-':(v*1000).toFixed(v<0.01?2:1)+' mm';
function show(s){
  $('state').textContent=s.registered?'tracking':'no pose';
  $('state').className=s.registered?'ok':'bad';
  $('frame').textContent=s.frame;
  $('fps').textContent=s.frames_per_second.toFixed(1);
  $('inview').textContent=s.targets_in_view;
  $('mapped').textContent=s.targets_mapped+' / '+s.targets_seen_total;
  $('depth').textContent=s.depth_m?s.depth_m.toFixed(2)+' m':'-';
  $('noise').textContent=s.image_noise_px.toFixed(2)+' px';
  $('perr').textContent=mm(s.predicted_point_error_m);
  $('cerr').textContent=mm(s.predicted_position_error_m);
  $('warnings').innerHTML='';
  for(const w of s.warnings){const li=document.createElement('li');li.textContent=w;$('warnings').appendChild(li);}
  $('coverage').innerHTML='';
  for(const c of s.coverage){const tr=document.createElement('tr');
    for(const v of [c.id,c.times_seen,c.direction_spread_deg.toFixed(0)+'\u00b0',c.sectors_covered+'/8',
      c.min_tilt_deg.toFixed(0)+'\u2013'+c.max_tilt_deg.toFixed(0)+'\u00b0']){
      const td=document.createElement('td');td.textContent=v;tr.appendChild(td);}
    $('coverage').appendChild(tr);}
}
const events=new EventSource('/events');
events.onmessage=e=>show(JSON.parse(e.data));
fetch('/status').then(r=>r.json()).then(s=>{if(s.frame!==undefined)show(s);}).catch(()=>{});
</script></body></html>
)HTML";

}  // namespace tagsfm
