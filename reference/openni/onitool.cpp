// onitool: OpenNI 1.x's own reading and writing of .oni recordings, for checking kinectdata.
//
//   onitool dump FILE OUTDIR
//       plays FILE back with OpenNI's player (fastest speed, no repeat) and writes, per
//       depth/image/IR node, OUTDIR/<node>.raw (the decoded frames, concatenated) and
//       OUTDIR/<node>.txt (one line per frame: frame id, timestamp in us, bytes, width, height).
//   onitool bench FILE NODE REPEATS
//       decodes NODE's frames REPEATS times and prints "frames seconds" (OpenNI's decode speed).
//   onitool record BASE OUT KIND:RAW:WIDTH:HEIGHT:FRAMES:CODEC:FPS [...]
//       records OUT with OpenNI's recorder from mock nodes based on BASE's nodes of that KIND
//       (depth, image, ir), fed the frames in RAW (uint16 or RGB888, concatenated); CODEC is a
//       FourCC (16zT, 16zP, Im8z, JPEG, NONE).
//
// Build: g++ -O2 onitool.cpp -I/usr/include/ni -lOpenNI -o onitool
// OpenNI 1.x needs its modules registered once: niReg -r /usr/lib/libnimMockNodes.so (and
// libnimCodecs.so, libnimRecorder.so).

#include <XnCppWrapper.h>
#include <XnCodecIDs.h>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

static int fail(const char* what, XnStatus rc) {
    fprintf(stderr, "onitool: %s: %s\n", what, xnGetStatusString(rc));
    return 2;
}

static bool openRecording(xn::Context& ctx, xn::Player& player, const char* file) {
    XnStatus rc = ctx.Init();
    if (rc != XN_STATUS_OK) { fail("init", rc); return false; }
    rc = ctx.OpenFileRecording(file, player);
    if (rc != XN_STATUS_OK) { fail(file, rc); return false; }
    player.SetRepeat(FALSE);
    player.SetPlaybackSpeed(XN_PLAYBACK_SPEED_FASTEST);
    return true;
}

static std::vector<std::string> mapNodes(xn::Player& player) {
    std::vector<std::string> names;
    xn::NodeInfoList list;
    if (player.EnumerateNodes(list) != XN_STATUS_OK) return names;
    for (xn::NodeInfoList::Iterator it = list.Begin(); it != list.End(); ++it) {
        XnProductionNodeType t = (*it).GetDescription().Type;
        if (t == XN_NODE_TYPE_DEPTH || t == XN_NODE_TYPE_IMAGE || t == XN_NODE_TYPE_IR)
            names.push_back((*it).GetInstanceName());
    }
    return names;
}

// Plays one node from the start to the end, calling back with each new frame.
template <class F>
static int playNode(const char* file, const std::string& name, F onFrame) {
    xn::Context ctx;
    xn::Player player;
    if (!openRecording(ctx, player, file)) return 2;
    xn::MapGenerator gen;
    XnStatus rc = ctx.GetProductionNodeByName(name.c_str(), gen);
    if (rc != XN_STATUS_OK) return fail(name.c_str(), rc);
    XnUInt32 total = 0;
    player.GetNumFrames(name.c_str(), total);
    XnUInt32 last = 0;
    for (XnUInt32 n = 0; total == 0 || n < total; ) {  // 1.0.0.4 files do not give a frame count
        rc = ctx.WaitOneUpdateAll(gen);
        if (rc != XN_STATUS_OK) { if (rc == XN_STATUS_EOF) break; return fail("read", rc); }
        if (gen.GetFrameID() != last) {
            last = gen.GetFrameID();
            XnMapOutputMode mode;
            gen.GetMapOutputMode(mode);
            onFrame(gen, mode);
            ++n;
        }
        if (player.IsEOF()) break;
    }
    ctx.Release();
    return 0;
}

static int dump(const char* file, const char* outdir) {
    std::vector<std::string> names;
    {
        xn::Context ctx;
        xn::Player player;
        if (!openRecording(ctx, player, file)) return 2;
        names = mapNodes(player);
        ctx.Release();
    }
    for (const std::string& name : names) {
        std::string base = std::string(outdir) + "/" + name;
        FILE* raw = fopen((base + ".raw").c_str(), "wb");
        FILE* txt = fopen((base + ".txt").c_str(), "w");
        if (!raw || !txt) { fprintf(stderr, "onitool: cannot write in %s\n", outdir); return 2; }
        int rc = playNode(file, name, [&](xn::MapGenerator& gen, const XnMapOutputMode& mode) {
            fwrite(gen.GetData(), 1, gen.GetDataSize(), raw);
            fprintf(txt, "%u %llu %u %u %u\n", gen.GetFrameID(), (unsigned long long)gen.GetTimestamp(),
                    gen.GetDataSize(), mode.nXRes, mode.nYRes);
        });
        fclose(raw);
        fclose(txt);
        if (rc) return rc;
    }
    return 0;
}

static int bench(const char* file, const char* name, int repeats) {
    int frames = 0;
    double seconds = 0;
    for (int r = 0; r < repeats; ++r) {
        auto t0 = std::chrono::steady_clock::now();
        int rc = playNode(file, name, [&](xn::MapGenerator&, const XnMapOutputMode&) { ++frames; });
        seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (rc) return rc;
    }
    printf("%d %.6f\n", frames, seconds);
    return 0;
}

struct Feed {
    std::string kind, raw, codec;
    unsigned w, h, frames, fps;
};

static bool parseFeed(const char* arg, Feed& f) {
    char kind[16], raw[4096], codec[8];
    if (sscanf(arg, "%15[^:]:%4095[^:]:%u:%u:%u:%7[^:]:%u", kind, raw, &f.w, &f.h, &f.frames, codec, &f.fps) != 7)
        return false;
    f.kind = kind; f.raw = raw; f.codec = codec;
    return f.codec.size() == 4;
}

static int record(const char* base, const char* out, int n, char** feeds) {
    xn::Context ctx;
    xn::Player player;
    if (!openRecording(ctx, player, base)) return 2;
    xn::Recorder recorder;
    XnStatus rc = recorder.Create(ctx);
    if (rc != XN_STATUS_OK) return fail("recorder", rc);
    rc = recorder.SetDestination(XN_RECORD_MEDIUM_FILE, out);
    if (rc != XN_STATUS_OK) return fail(out, rc);
    std::vector<Feed> fs(n);
    std::vector<xn::MockDepthGenerator> depths;
    std::vector<xn::MockImageGenerator> images;
    std::vector<xn::MockIRGenerator> irs;
    depths.reserve(n); images.reserve(n); irs.reserve(n);
    std::vector<FILE*> raws(n);
    for (int i = 0; i < n; ++i) {
        if (!parseFeed(feeds[i], fs[i])) { fprintf(stderr, "onitool: bad feed %s\n", feeds[i]); return 2; }
        Feed& f = fs[i];
        XnCodecID codec = XN_CODEC_ID(f.codec[0], f.codec[1], f.codec[2], f.codec[3]);
        XnMapOutputMode mode = {f.w, f.h, f.fps};
        std::string name = "kd_" + f.kind + std::to_string(i);
        raws[i] = fopen(f.raw.c_str(), "rb");
        if (!raws[i]) { fprintf(stderr, "onitool: cannot read %s\n", f.raw.c_str()); return 2; }
        if (f.kind == "depth") {
            xn::DepthGenerator src;
            if ((rc = ctx.FindExistingNode(XN_NODE_TYPE_DEPTH, src)) != XN_STATUS_OK) return fail("base depth", rc);
            depths.emplace_back();
            if ((rc = depths.back().CreateBasedOn(src, name.c_str())) != XN_STATUS_OK) return fail("mock depth", rc);
            if ((rc = depths.back().SetMapOutputMode(mode)) != XN_STATUS_OK) return fail("depth mode", rc);
            if ((rc = recorder.AddNodeToRecording(depths.back(), codec)) != XN_STATUS_OK) return fail("add depth", rc);
        } else if (f.kind == "image") {
            xn::ImageGenerator src;
            if ((rc = ctx.FindExistingNode(XN_NODE_TYPE_IMAGE, src)) != XN_STATUS_OK) return fail("base image", rc);
            images.emplace_back();
            if ((rc = images.back().CreateBasedOn(src, name.c_str())) != XN_STATUS_OK) return fail("mock image", rc);
            if ((rc = images.back().SetMapOutputMode(mode)) != XN_STATUS_OK) return fail("image mode", rc);
            if ((rc = images.back().SetPixelFormat(XN_PIXEL_FORMAT_RGB24)) != XN_STATUS_OK) return fail("image format", rc);
            if ((rc = recorder.AddNodeToRecording(images.back(), codec)) != XN_STATUS_OK) return fail("add image", rc);
        } else {
            fprintf(stderr, "onitool: kind must be depth or image, not %s\n", f.kind.c_str());
            return 2;
        }
    }
    // frames in time order, interleaved between the feeds as a device delivers them
    std::vector<unsigned> next(n, 0);
    std::vector<unsigned char> buffer;
    for (;;) {
        int pick = -1;
        double best = 1e300;
        for (int i = 0; i < n; ++i) {
            if (next[i] >= fs[i].frames) continue;
            double t = next[i] * 1e6 / fs[i].fps;
            if (t < best) { best = t; pick = i; }
        }
        if (pick < 0) break;
        Feed& f = fs[pick];
        size_t bytes = (size_t)f.w * f.h * (f.kind == "depth" ? 2 : 3);
        buffer.resize(bytes);
        if (fread(buffer.data(), 1, bytes, raws[pick]) != bytes) { fprintf(stderr, "onitool: %s too short\n", f.raw.c_str()); return 2; }
        XnUInt64 ts = (XnUInt64)(next[pick] * 1e6 / f.fps + 0.5);
        XnUInt32 id = next[pick] + 1;
        int k = 0, d = 0, im = 0;
        for (int i = 0; i < pick; ++i) (fs[i].kind == "depth" ? d : im)++;
        (void)k;
        if (f.kind == "depth")
            rc = depths[d].SetData(id, ts, (XnUInt32)bytes, (const XnDepthPixel*)buffer.data());
        else
            rc = images[im].SetData(id, ts, (XnUInt32)bytes, buffer.data());
        if (rc != XN_STATUS_OK) return fail("set data", rc);
        if ((rc = recorder.Record()) != XN_STATUS_OK) return fail("record", rc);
        ++next[pick];
    }
    for (FILE* r : raws) fclose(r);
    recorder.Release();
    ctx.Release();
    return 0;
}

int main(int argc, char** argv) {
    if (argc >= 4 && !strcmp(argv[1], "dump")) return dump(argv[2], argv[3]);
    if (argc == 5 && !strcmp(argv[1], "bench")) return bench(argv[2], argv[3], atoi(argv[4]));
    if (argc >= 5 && !strcmp(argv[1], "record")) return record(argv[2], argv[3], argc - 4, argv + 4);
    fprintf(stderr, "usage: onitool dump FILE OUTDIR | bench FILE NODE REPEATS | record BASE OUT FEED...\n");
    return 2;
}
