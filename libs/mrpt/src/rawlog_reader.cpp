// SPDX-License-Identifier: BSD-3-Clause
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <opencv2/imgproc.hpp>

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/lazy_load_path.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CActionRobotMovement3D.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/rtti/CObject.h>
#include <mrpt/serialization/CArchive.h>

#include "cleanmap/core/error.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/rawlog.h"
#include "cleanmap/vision/rectify.h"

namespace fs = std::filesystem;

namespace cleanmap::mrpt {
namespace {

// MRPT decodes a JPEG image inside a rawlog with libjpeg's default error handler, which ends the
// process (exit(1), "Not a JPEG file") on corrupt data: nothing can be caught. The entry being
// deserialized is recorded so that the process at least says which file and entry killed it.
std::mutex g_reading_mutex;
std::string g_reading;  // "<path> entry <n>" while an entry is deserialized, else empty

void sayWhatWasRead() {
  std::lock_guard<std::mutex> lock(g_reading_mutex);
  if (!g_reading.empty())
    std::fprintf(stderr,
                 "cleanmap: %s: corrupt rawlog entry: MRPT's decoder ended the process while "
                 "reading it (a corrupt JPEG image?)\n",
                 g_reading.c_str());
}

class ReadingGuard {
 public:
  ReadingGuard(const std::string& path, std::size_t entry) {
    static const bool registered = std::atexit(sayWhatWasRead) == 0;
    (void)registered;
    std::lock_guard<std::mutex> lock(g_reading_mutex);
    g_reading = path + " entry " + std::to_string(entry);
  }
  ~ReadingGuard() {
    std::lock_guard<std::mutex> lock(g_reading_mutex);
    g_reading.clear();
  }
  ReadingGuard(const ReadingGuard&) = delete;
  ReadingGuard& operator=(const ReadingGuard&) = delete;
};

// gzread failed: the compressed data is damaged (its check at the end, or the deflate data).
struct CorruptCompressedData : std::runtime_error {
  CorruptCompressedData() : std::runtime_error("corrupt compressed data (gzread failed)") {}
};

// The bytes after an object's version byte that objectProblem looks at (a CImage's header: 22).
constexpr size_t kCheckedBytes = 24;

// A little-endian field of `bytes` bytes at `at` of `b`; nullopt past its end.
std::optional<uint64_t> fieldAt(const std::string& b, size_t at, size_t bytes) {
  if (b.size() < at + bytes) return std::nullopt;
  uint64_t v = 0;
  for (size_t i = bytes; i-- > 0;) v = (v << 8) | static_cast<uint8_t>(b[at + i]);
  return v;
}

// a * b * c, or UINT64_MAX where that overflows.
uint64_t product(uint64_t a, uint64_t b, uint64_t c) {
  uint64_t ab = 0, abc = 0;
  if (__builtin_mul_overflow(a, b, &ab) || __builtin_mul_overflow(ab, c, &abc)) return UINT64_MAX;
  return abc;
}

// What MRPT 2.5.8's CImage reader does not check, in each version it reads: it allocates a JPEG's
// byte count (zero-filled: a 3 KB rawlog took 4.2 GB) or the pixels of the size it reads before
// reading them, and in version 0 it reads a byte count apart from that size into the image (more
// overflows the heap: a 2 x 2 image given 200,000 bytes aborted a run in malloc). Every pixel or
// JPEG byte MRPT allocates is in a file it wrote, so more than max_bytes of them is corrupt; so is
// a version 0 count over the image's size (MRPT 2.5.8 would overflow it). External images (a file
// name) and sizes OpenCV refuses (negative) are MRPT's to read. `after`: the bytes after the
// version byte.
std::string imageProblem(int version, const std::string& after, uint64_t max_bytes) {
  const auto u = [&](size_t at, size_t bytes) { return fieldAt(after, at, bytes); };
  const auto i32 = [&](size_t at) -> std::optional<int64_t> {
    const auto v = u(at, 4);
    if (!v) return std::nullopt;
    return static_cast<int64_t>(static_cast<int32_t>(static_cast<uint32_t>(*v)));
  };
  const auto jpeg = [&](size_t at) -> std::string {
    const auto n = u(at, 4);
    if (!n || *n <= max_bytes) return "";
    return "a CImage claiming " + std::to_string(*n) +
           " bytes of JPEG data, more than the file can hold (corrupt)";
  };
  // "w x h pixels of n bytes"
  const auto size = [](uint64_t w, uint64_t h, uint64_t bytes) {
    return std::to_string(w) + " x " + std::to_string(h) + " pixels of " + std::to_string(bytes) +
           (bytes == 1 ? " byte" : " bytes");
  };
  const auto pixels = [&](uint64_t w, uint64_t h, uint64_t bytes) -> std::string {
    if (product(w, h, bytes) <= max_bytes) return "";
    return "a CImage claiming " + size(w, h, bytes) + ", more than the file can hold (corrupt)";
  };
  if (version == 0) {  // width, height, channels (uint32), origin (uint8), byte count (uint32)
    const auto w = u(0, 4), h = u(4, 4), c = u(8, 4), n = u(13, 4);
    if (!w || !h || !c || !n) return "";
    // 1 to 4 channels: OpenCV's type keeps the count modulo 512 (513 would make 1).
    if (*c < 1 || *c > 4) return "a CImage of " + std::to_string(*c) + " channels (corrupt)";
    if (product(*w, *h, *c) < *n)
      return "a CImage of " + size(*w, *h, *c) + " claiming " + std::to_string(*n) +
             " bytes of them (corrupt: MRPT would write past the image)";
    return pixels(*w, *h, *c);
  }
  if (version == 1) return jpeg(0);
  if (version < 2 || version > 9) return "";  // 100: a file name; others MRPT refuses
  size_t at = 0;
  if (version >= 6) {
    const auto external = u(at++, 1);
    if (!external || *external != 0) return "";
  }
  const auto colour = u(at++, 1);
  if (!colour) return "";
  if (*colour == 0) {  // grey: width, height, origin, byte count (int32), depth (version 9)
    const auto w = i32(at), h = i32(at + 4);
    if (!w || !h || *w < 0 || *h < 0) return "";
    uint64_t bytes = 1;
    if (version >= 9) {
      // OpenCV's depth codes (mrpt::img::PixelDepth): 8-bit, 16-bit, 32-bit and 64-bit
      // pixels; an unknown one counted as 1 byte (OpenCV decides).
      static constexpr uint64_t kBytes[] = {1, 1, 2, 2, 4, 4, 8};
      const auto depth = u(at + 16, 4);
      if (!depth) return "";
      if (*depth < 7) bytes = kBytes[*depth];
    }
    return pixels(static_cast<uint64_t>(*w), static_cast<uint64_t>(*h), bytes);
  }
  if (version < 7) return jpeg(at);
  const auto w = i32(at), h = i32(at + 4);  // positive: JPEG; both negative: raw RGB
  if (!w || !h) return "";
  if (*w >= 1 && *h >= 1) return jpeg(at + 8);
  if (*w < 0 && *h < 0) return pixels(static_cast<uint64_t>(-*w), static_cast<uint64_t>(-*h), 3);
  return "";
}

// What MRPT 2.5.8's readers of its containers do not check (found by fuzzing and by reading them):
// a CSimpleMap, CSensoryFrame or CActionCollection sizes its list (a std::deque, filled block by
// block) to the count it reads first, so a few bytes claiming 2^32 elements take gigabytes before
// the data runs out; a points map zero-fills three to six arrays of the count it reads first (64 GB
// for 2^32 points of CPointsMapXYZI); and the first formats (version 0) of a CSimpleMap and a
// CSensoryFrame use a pose or an observation that may be missing (SIGSEGV). A count is refused
// where its elements, each at least a missing object ("nullptr", 9 bytes) or a point's x, y and
// z (12 bytes), would not fit in max_bytes. A point-cloud SLAM never wrote a version 0: MRPT
// 2.5.8 writes version 1 of a CSimpleMap and 2 of a CSensoryFrame. Images: imageProblem.
// `name`: the class MRPT names in the object's header, `after`: the bytes after its version byte
// (kCheckedBytes of them, fewer at the end of the file). The class is the one MRPT's reader makes
// of the name: the name's, or where no class has that name, the one named by its part after the
// last "::" (MRPT 1 wrote no namespaces; any prefix passes). "" where it is no such class or
// nothing is wrong, else what is wrong ("a CSensoryFrame claiming ...").
std::string objectProblem(const std::string& name, int version, const std::string& after,
                          uint64_t max_bytes) {
  constexpr uint64_t kLeastObjectBytes = 9, kLeastPointBytes = 12;
  // MRPT reads the name as a C string: it ends at its first NUL.
  const ::mrpt::rtti::TRuntimeClassId* id =
      ::mrpt::rtti::findRegisteredClass(name.substr(0, name.find('\0')));
  if (!id || !id->className) return "";
  const std::string full = id->className, cls = full.substr(full.rfind(':') + 1);
  if (full == "mrpt::img::CImage") return imageProblem(version, after, max_bytes);
  uint64_t per_element = kLeastObjectBytes;
  size_t count_at = 0;
  std::string elements = " elements";
  if (full == "mrpt::maps::CSimpleMap") {
    per_element = 2 * kLeastObjectBytes;  // a pose and a sensory frame
    elements = " keyframes";
  } else if (full == "mrpt::obs::CSensoryFrame") {
    count_at = version == 1 ? 4 : 0;  // an ID before it
  } else if (full == "mrpt::maps::CSimplePointsMap" || full == "mrpt::maps::CPointsMapXYZI" ||
             full == "mrpt::maps::CPointsMapXYZIRT" || full == "mrpt::maps::CColouredPointsMap") {
    per_element = kLeastPointBytes;  // every version starts with the count
    elements = " points";
  } else if (full != "mrpt::obs::CActionCollection") {
    return "";
  }
  if (version == 0 && (cls == "CSimpleMap" || cls == "CSensoryFrame"))
    return "a " + cls + " of MRPT's first format (version 0), which cleanmap does not read";
  const auto n = fieldAt(after, count_at, 4);
  if (!n || *n * per_element <= max_bytes) return "";  // cut short: MRPT's reader says so
  return "a " + cls + " claiming " + std::to_string(*n) + elements +
         ", more than the file can hold (corrupt)";
}

// MRPT's input stream with read-ahead: the next object's header is read (peekHeader) and read
// again by MRPT's deserializer. With watchObjects, each container or image MRPT reads inside
// another (a simplemap's keyframes, a frame's observations, an observation's image) is checked as
// its header goes by (objectProblem): MRPT reads a header's name length (high bit set), then the
// name, each in one Read, so a read of a class name after its length is one.
class PeekStream : public ::mrpt::io::CStream {
 public:
  explicit PeekStream(::mrpt::io::CStream& in) : in_(in) {}
  size_t Read(void* out, size_t n) override {
    const size_t got = std::min(n, ahead_.size() - at_);
    std::memcpy(out, ahead_.data() + at_, got);
    at_ += got;
    const size_t total = got + (got < n ? readFile(static_cast<char*>(out) + got, n - got) : 0);
    if (watch_bytes_ > 0) watch(static_cast<const char*>(out), total);
    return total;
  }
  size_t Write(const void*, size_t) override { throw std::logic_error("PeekStream is read-only"); }
  uint64_t Seek(int64_t, TSeekOrigin) override { throw std::logic_error("PeekStream cannot seek"); }
  uint64_t getTotalBytesCount() const override { return in_.getTotalBytesCount(); }
  uint64_t getPosition() const override { return in_.getPosition() - (ahead_.size() - at_); }
  // A read failed on corrupt compressed data (MRPT's deserializer turns that into its "EOF").
  bool corrupt() const { return corrupt_; }
  // Checks the containers and images inside others against the most bytes the file can hold
  // (mostBytesIn).
  void watchObjects(uint64_t max_bytes) { watch_bytes_ = max_bytes; }
  // What was wrong with an object inside another ("a CSensoryFrame claiming ..."), or "": the
  // read was stopped by an exception MRPT's reader passes on in its own words.
  const std::string& refused() const { return refused_; }
  // The next n bytes (fewer at the end of the stream), left to be read.
  std::string peek(size_t n) {
    ahead_.erase(0, at_);
    at_ = 0;
    if (ahead_.size() < n) {
      std::string more(n - ahead_.size(), '\0');
      more.resize(readFile(more.data(), more.size()));
      ahead_ += more;
    }
    return ahead_.substr(0, n);
  }

 private:
  // MRPT's gz stream returns gzread's -1 as a count on corrupt compressed data.
  size_t readFile(char* out, size_t n) {
    const size_t got = in_.Read(out, n);
    if (got > n) {
      corrupt_ = true;
      throw CorruptCompressedData();
    }
    return got;
  }
  void watch(const char* bytes, size_t n) {
    const uint8_t length = length_;
    length_ = n == 1 ? static_cast<uint8_t>(bytes[0]) : 0;
    if (n == 1 || length != (0x80 | n)) return;
    const std::string name(bytes, n);
    const std::string next = peek(1 + kCheckedBytes);  // the version byte, then what follows
    if (next.empty()) return;
    refused_ = objectProblem(name, static_cast<int8_t>(next[0]), next.substr(1), watch_bytes_);
    if (!refused_.empty()) throw std::runtime_error(refused_);
  }
  ::mrpt::io::CStream& in_;
  bool corrupt_ = false;
  std::string ahead_;  // bytes read from in_ and not yet by Read
  size_t at_ = 0;
  uint64_t watch_bytes_ = 0;  // watchObjects' bound; 0: no watch
  uint8_t length_ = 0;        // the byte of the last one-byte Read
  std::string refused_;
};

// The next object's header, read ahead as CArchive::ReadObject reads it (a name length with its
// high bit set, the name, a version byte; before MRPT 0.5.5: the length, three zero bytes, the
// name, a 32-bit version), and its size in bytes. nullopt where the bytes are no such header:
// MRPT's reader then says what is wrong.
struct Header {
  std::string name;
  int version = 0;
  size_t bytes = 0;
};
std::optional<Header> peekHeader(PeekStream& s) {
  const std::string first = s.peek(1);
  if (first.empty()) return std::nullopt;
  const auto len0 = static_cast<uint8_t>(first[0]);
  const bool old = !(len0 & 0x80);
  const size_t len = len0 & 0x7F, name_at = old ? 4 : 1;
  const size_t bytes = name_at + len + (old ? 4 : 1);
  const std::string b = s.peek(bytes);
  if (b.size() < bytes) return std::nullopt;
  const int version = old ? static_cast<int>(static_cast<uint32_t>(*fieldAt(b, name_at + len, 4)))
                          : static_cast<int8_t>(b[name_at + len]);
  return Header{b.substr(name_at, len), version, bytes};
}

// objectProblem of the next object, a top-level one, before MRPT reads it; the containers and
// images inside it are checked as MRPT reads them (watchObjects). `what`: "is", "entry N is".
void checkObject(PeekStream& s, const std::string& path, const std::string& what,
                 uint64_t max_bytes) {
  s.watchObjects(max_bytes);
  const auto h = peekHeader(s);
  if (!h) return;
  const std::string b = s.peek(h->bytes + kCheckedBytes);
  const std::string problem =
      objectProblem(h->name, h->version, b.size() > h->bytes ? b.substr(h->bytes) : "", max_bytes);
  if (!problem.empty()) throw Error(path, what + " " + problem);
}

// The most bytes a file's objects can take: its size, or as much as deflate can expand it to
// (1032:1) where it is compressed.
uint64_t mostBytesIn(const std::string& path) {
  std::error_code ec;
  const uint64_t size = fs::file_size(path, ec);
  if (ec) return UINT64_MAX;
  char magic[2] = {};
  std::ifstream(path, std::ios::binary).read(magic, 2);
  return magic[0] == '\x1f' && magic[1] == '\x8b' ? size * 1032 : size;
}

struct Item {
  enum Kind { kScan, kPose, kImage, kOdometry } kind = kScan;
  double t = 0;
  std::size_t entry = 0;                                  // 0-based rawlog entry it came from
  Scan scan;                                              // kScan
  ::mrpt::poses::CPose3D sensor_pose;                     // kScan: lidar on robot
  ::mrpt::poses::CPose3D robot_pose;                      // kPose, kOdometry
  std::optional<::mrpt::poses::CPose3D> action_odometry;  // kScan: odometry from the actions so far
  std::optional<::mrpt::poses::CPose3D> keyframe_pose;    // kScan of a simplemap: its robot pose
  ::mrpt::obs::CObservationImage::Ptr img;                // kImage
};

}  // namespace

struct RawlogSource::Impl {
  std::string path;
  RawlogReadOptions opts;
  ::mrpt::io::CFileGZInputStream file;
  PeekStream in{file};
  uint64_t max_bytes = UINT64_MAX;  // the most the file's objects can take (mostBytesIn)
  std::size_t entry = 0, scans = 0, skipped = 0;
  bool eof = false;
  std::deque<Item> buf;
  std::optional<PinholeCamera> camera;
  std::optional<vision::Rectifier> rectifier;      // the camera has lens distortion (DESIGN §3)
  std::optional<::mrpt::poses::CPose3D> odometry;  // robot odometry summed from actions
  std::string lidar, cam;                          // the sensorLabels read
  std::map<std::string, std::size_t> other_lidars, other_cameras;
  std::map<std::string, std::size_t> skipped_classes;  // observations not read, by class
  std::optional<double> last_scan_t;                   // the time of the scan read before
  std::size_t timed_back = 0;                          // scans timed before the one before
  std::string first_timed_back;
  std::set<std::string> external_dirs;  // folders of the external files read (absolute)
  // A simplemap (one CSimpleMap object): its keyframes are read one per readEntry(), each freed
  // once pushed; `entry` then counts keyframes and the messages say so.
  ::mrpt::maps::CSimpleMap::Ptr simplemap;
  std::size_t keyframe = 0;
  std::optional<::mrpt::poses::CPose3D> keyframe_pose;  // of the keyframe being pushed
  bool keyframes = false;

  // "entry N" (a rawlog's) or "keyframe N" (a simplemap's), of the one read last.
  std::string where(std::size_t n) const {
    return (keyframes ? "keyframe " : "entry ") + std::to_string(n);
  }

  // One lidar and one camera per run (opts.lidar_label / camera_label, else the first seen).
  static bool ours(std::string& chosen, const std::string& wanted, const std::string& label,
                   std::map<std::string, std::size_t>& others) {
    if (chosen.empty()) chosen = wanted.empty() ? label : wanted;
    if (label == chosen) return true;
    ++others[label];
    return false;
  }

  // Odometry increments of an action collection (sensory-frame rawlogs): 3D if there is one,
  // else the best 2D estimate.
  void addActions(const ::mrpt::obs::CActionCollection& acts) {
    using namespace ::mrpt::obs;
    ::mrpt::poses::CPose3D inc;
    if (const auto a3 = acts.getActionByClass<CActionRobotMovement3D>())
      inc = a3->poseChange.mean;
    else if (const auto a2 = acts.getBestMovementEstimation())
      inc = ::mrpt::poses::CPose3D(a2->poseChange->getMeanVal());
    else
      return;
    odometry = odometry ? *odometry + inc : inc;
  }

  void push(const ::mrpt::obs::CObservation::Ptr& obs) {
    using namespace ::mrpt::obs;
    if (!obs) return;
    const double t = ::mrpt::Clock::toDouble(obs->timestamp);
    // Another lidar's scan is skipped before it is decoded (an error in it is not this run's).
    if (isLidarObservation(*obs) && !ours(lidar, opts.lidar_label, obs->sensorLabel, other_lidars))
      return;
    if (isLidarObservation(*obs)) requireExternals(*obs);
    std::optional<Scan> scan;
    try {
      scan = scanFromObservation(*obs);
    } catch (const Error& e) {  // name the rawlog and the entry too
      throw Error(path, where(entry - 1) + ": " + e.what());
    } catch (const std::exception& e) {  // MRPT's: its message only, not its banner and stack
      throw Error(path, where(entry - 1) + ": " + briefMessage(e));
    }
    if (scan) {
      Item it;
      it.kind = Item::kScan;
      it.t = t;
      it.scan = std::move(*scan);
      it.entry = entry - 1;
      it.action_odometry = odometry;
      it.keyframe_pose = keyframe_pose;
      obs->getSensorPose(it.sensor_pose);
      buf.push_back(std::move(it));
    } else if (auto rp = std::dynamic_pointer_cast<CObservationRobotPose>(obs)) {
      Item it;
      it.kind = Item::kPose;
      it.t = t;
      it.entry = entry - 1;
      it.robot_pose = rp->pose.mean;
      buf.push_back(std::move(it));
    } else if (auto od = std::dynamic_pointer_cast<CObservationOdometry>(obs)) {
      Item it;
      it.kind = Item::kOdometry;
      it.t = t;
      it.entry = entry - 1;
      it.robot_pose = ::mrpt::poses::CPose3D(od->odometry);
      buf.push_back(std::move(it));
    } else if (auto im = std::dynamic_pointer_cast<CObservationImage>(obs)) {
      if (!opts.load_images) return;  // laser only: not decoded, not counted
      if (!ours(cam, opts.camera_label, obs->sensorLabel, other_cameras)) return;
      for (const auto& f : externalFiles(*im, path, where(entry - 1)))
        noteExternal(f, false);  // read where a scan takes it
      Item it;
      it.kind = Item::kImage;
      it.t = t;
      it.entry = entry - 1;
      it.img = im;
      buf.push_back(std::move(it));
    } else {
      ++skipped;
      ++skipped_classes[obs->GetRuntimeClass()->className];
    }
  }

  // A file an observation of ours keeps outside the rawlog (MRPT's external storage): its folder
  // is recorded (no output may replace it). A scan's that is missing is an error naming the entry
  // (MRPT's own says only that an assertion failed); an image's is loaded, or found missing,
  // where a scan takes it.
  void noteExternal(const ExternalFile& f, bool required) {
    external_dirs.insert(fs::absolute(fs::path(f.path)).parent_path().lexically_normal().string());
    std::error_code ec;
    if (required && !fs::is_regular_file(f.path, ec))
      throw missingExternalFile(path, where(entry - 1), f);
  }
  void requireExternals(const ::mrpt::obs::CObservation& obs) {
    for (const auto& f : externalFiles(obs, path, where(entry - 1)))
      if (f.what != "image") noteExternal(f, true);
  }

  // Reads one rawlog entry; false at a clean end of file. We deserialize ourselves instead of
  // CRawlog::getActionObservationPairOrObservation, which prints and swallows errors, so a
  // truncated rawlog would look complete.
  bool readEntry() {
    if (simplemap) return readKeyframe();
    if (eof) return false;
    using namespace ::mrpt::obs;
    auto arch = ::mrpt::serialization::archiveFrom(in);
    const uint64_t before = in.getPosition();
    ::mrpt::serialization::CSerializable::Ptr obj;
    // gzread failed under MRPT's reader (which calls that an end of file) or ours.
    const auto corrupt = [&] {
      return Error(
          path, std::string(CorruptCompressedData().what()) + " at entry " + std::to_string(entry));
    };
    // A container or image inside the entry refused as MRPT read it (PeekStream::watchObjects).
    const auto refused = [&] {
      return Error(path, (entry == 0 ? "" : "entry " + std::to_string(entry) + " ") + "holds " +
                             in.refused());
    };
    try {
      checkObject(in, path, entry == 0 ? "is" : "entry " + std::to_string(entry) + " is",
                  max_bytes);
      const ReadingGuard guard(path, entry);
      obj = arch.ReadObject();
    } catch (const Error&) {
      throw;
    } catch (const ::mrpt::serialization::CExceptionEOF&) {
      if (in.corrupt()) throw corrupt();
      if (!in.refused().empty()) throw refused();
      if (in.getPosition() == before) {
        eof = true;
        return false;
      }
      if (entry == 0 && isSimplemapName(path))
        throw Error(path, "is a simplemap cut short (the file ends inside its one object)");
      if (entry == 0)
        throw Error(path, "is not an MRPT rawlog, or is truncated inside its first entry");
      throw Error(path, "truncated rawlog at entry " + std::to_string(entry) +
                            " (the file ends inside an object)");
    } catch (const std::exception& e) {
      if (in.corrupt()) throw corrupt();
      if (!in.refused().empty()) throw refused();
      if (entry == 0 && isSimplemapName(path))  // one object: MRPT's message says no more than this
        throw Error(path, "is not a simplemap MRPT can read (cut short, corrupt, or another file)");
      if (entry == 0)
        throw Error(path,
                    "is not an MRPT rawlog (its first entry is not a serialized MRPT object)");
      throw Error(path, "truncated or corrupt rawlog at entry " + std::to_string(entry) + ": " +
                            briefMessage(e));
    }
    ++entry;
    if (auto sf = std::dynamic_pointer_cast<CSensoryFrame>(obj)) {
      for (const auto& o : *sf) push(o);
    } else if (auto obs = std::dynamic_pointer_cast<CObservation>(obj)) {
      push(obs);
    } else if (auto acts = std::dynamic_pointer_cast<CActionCollection>(obj)) {
      addActions(*acts);
    } else if (auto sm = std::dynamic_pointer_cast<::mrpt::maps::CSimpleMap>(obj);
               sm && entry == 1) {  // a .simplemap file: one object, its keyframes
      simplemap = std::move(sm);
      keyframes = true;
      entry = 0;
    } else {
      ++skipped;  // anything else
      if (obj) ++skipped_classes[obj->GetRuntimeClass()->className];
    }
    return true;
  }

  // The next keyframe of a simplemap (a SLAM's output): its observations at its pose, each scan
  // posed by its keyframe (not by time: a simplemap's times may be missing). False after the last.
  bool readKeyframe() {
    if (keyframe >= simplemap->size()) {
      simplemap.reset();
      eof = true;
      return false;
    }
    auto& kf = simplemap->getAsPair(keyframe++);
    ++entry;
    if (!kf.pose || !kf.sf) throw Error(path, where(entry - 1) + " has no pose or no observations");
    keyframe_pose = kf.pose->getMeanVal();
    for (const auto& o : *kf.sf) push(o);
    keyframe_pose.reset();
    kf.sf.reset();  // read: freed
    return true;
  }

  std::optional<std::size_t> findScan(std::size_t from) const {
    for (std::size_t i = from; i < buf.size(); ++i)
      if (buf[i].kind == Item::kScan) return i;
    return std::nullopt;
  }

  // The item of `kind` in [0, end) nearest in time to t, within tol.
  // In a simplemap (`of_keyframe` given): only that keyframe's items, whatever their times.
  const Item* nearest(Item::Kind kind, double t, double tol, std::size_t end,
                      std::optional<std::size_t> of_keyframe = std::nullopt) const {
    const Item* best = nullptr;
    for (std::size_t i = 0; i < end; ++i) {
      const Item& it = buf[i];
      if (it.kind != kind) continue;
      if (of_keyframe ? it.entry != *of_keyframe : std::abs(it.t - t) > tol) continue;
      if (!best || std::abs(it.t - t) < std::abs(best->t - t)) best = &it;
    }
    return best;
  }

  // The camera from the first image's TCamera. A distorted one (plumb_bob, or coefficients with
  // no model named; kannala_brandt) is made pinhole: its images are rectified as they are read.
  void learnCamera(const ::mrpt::obs::CObservationImage& img,
                   const ::mrpt::poses::CPose3D& lidar_pose) {
    using ::mrpt::img::DistortionModel;
    ::mrpt::img::TCamera tc = img.cameraParams;
    // MRPT keeps any uint32 size; the rectifier's maps are sized by it (found by fuzzing: 128 GB).
    constexpr uint32_t kMaxImageSide = 1u << 15;
    if (tc.ncols < 1 || tc.nrows < 1 || tc.ncols > kMaxImageSide || tc.nrows > kMaxImageSide)
      throw Error(path, "camera '" + img.sensorLabel + "': its calibration gives images of " +
                            std::to_string(tc.ncols) + " x " + std::to_string(tc.nrows) +
                            " pixels; a camera's are 1 to " + std::to_string(kMaxImageSide) +
                            " pixels a side");
    const auto& d = tc.dist;
    const bool fisheye = tc.distortion == DistortionModel::kannala_brandt;
    const bool distorted =
        fisheye || std::any_of(d.begin(), d.end(), [](double x) { return x != 0; });
    if (distorted) {
      vision::Lens lens;
      lens.model = fisheye ? vision::LensModel::kKannalaBrandt : vision::LensModel::kPlumbBob;
      if (fisheye)
        lens.k = {tc.k1(), tc.k2(), tc.k3(), tc.k4(), 0, 0, 0, 0};
      else
        std::copy(d.begin(), d.end(), lens.k.begin());
      const std::string where = path + " camera '" + img.sensorLabel + "'";
      rectifier.emplace(tc.intrinsicParams.asEigen(), lens, static_cast<int>(tc.ncols),
                        static_cast<int>(tc.nrows), where);
      const Eigen::Matrix3d& K = rectifier->K();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) tc.intrinsicParams(r, c) = K(r, c);
      tc.distortion = DistortionModel::none;
      tc.dist.fill(0);
    }
    camera = fromTCamera(tc, img.cameraPose, lidar_pose, path);
  }

  Image toImage(const Item& it) {
    cv::Mat m;
    try {
      it.img->image.asCvMat(m, ::mrpt::img::DEEP_COPY);
    } catch (const std::exception& e) {
      throw Error(path, where(it.entry) + ": cannot load its image: " + briefMessage(e));
    }
    if (m.empty()) throw Error(path, where(it.entry) + ": the image is empty");
    if (rectifier) {
      if (camera && (m.cols != camera->width || m.rows != camera->height))
        throw Error(path, "image at t=" + std::to_string(it.t) + " is " + std::to_string(m.cols) +
                              "x" + std::to_string(m.rows) + " px, its camera's calibration " +
                              std::to_string(camera->width) + "x" + std::to_string(camera->height));
      m = rectifier->apply(m);
    }
    Image img;
    if (m.channels() == 1)
      cv::cvtColor(m, img.bgr, cv::COLOR_GRAY2BGR);
    else
      img.bgr = m;
    img.timestamp = it.t;
    return img;
  }
};

RawlogSource::RawlogSource(const std::string& path, const RawlogReadOptions& opts)
    : impl_(std::make_unique<Impl>()) {
  registerClasses();
  impl_->path = path;
  impl_->opts = opts;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(path, "file does not exist");
  if (fs::is_directory(path, ec)) throw Error(path, "is a directory, expected a rawlog file");
  if (!impl_->file.open(path)) throw Error(path, "cannot open for reading");
  impl_->max_bytes = mostBytesIn(path);
  useExternalFilesFolderOf(path);
  while (!impl_->findScan(0) && impl_->readEntry()) {
  }
  if (impl_->keyframes && impl_->entry == 0) throw Error(path, "is a simplemap with no keyframes");
  if (impl_->entry == 0)  // a compressed file cut inside its first block reads as a clean end
    throw Error(path, fs::file_size(path, ec) == 0
                          ? "is empty (0 bytes)"
                          : "holds no complete MRPT object (cut short, or not a rawlog)");
  if (!impl_->findScan(0) && !impl_->other_lidars.empty())
    throw Error(path, "holds no scans of lidar '" + impl_->lidar +
                          "'; its lidars: " + labelCounts(impl_->other_lidars));
  if (!impl_->findScan(0)) {
    std::string held;  // what it holds instead, most frequent first
    std::vector<std::pair<std::size_t, std::string>> by_count;
    for (const auto& [name, n] : impl_->skipped_classes) by_count.emplace_back(n, name);
    std::sort(by_count.rbegin(), by_count.rend());
    for (const auto& [n, name] : by_count)
      held += (held.empty() ? "; it holds " : ", ") + name + " (" + std::to_string(n) + ")";
    throw Error(path,
                "holds no point-cloud observations (CObservationPointCloud, "
                "CObservationVelodyneScan, CObservationRotatingScan or CObservation3DRangeScan)" +
                    held);
  }
}

RawlogSource::~RawlogSource() = default;

std::optional<Frame> RawlogSource::next() {
  auto& I = *impl_;
  while (!I.findScan(0) && I.readEntry()) {
  }
  const auto s = I.findScan(0);
  if (!s) return std::nullopt;
  while (!I.findScan(*s + 1) && I.readEntry()) {
  }
  const std::size_t end = I.findScan(*s + 1).value_or(I.buf.size());

  Item& cur = I.buf[*s];
  Frame f;
  f.index = I.scans++;
  char stem[16];
  std::snprintf(stem, sizeof stem, "%06zu", f.index);
  f.stem = stem;
  f.source = I.path + " " + I.where(cur.entry);
  f.scan = std::move(cur.scan);
  f.scan.timestamp = cur.t;
  if (I.last_scan_t && cur.t < *I.last_scan_t && !I.timed_back++) {
    char when[96];
    std::snprintf(when, sizeof when, ": t = %.6f s, %.3f s before the scan before", cur.t,
                  *I.last_scan_t - cur.t);
    I.first_timed_back = f.source + when;
  }
  I.last_scan_t = cur.t;
  f.mount = toIsometry(cur.sensor_pose);  // issue #15: a tilted lidar is levelled by its mount
  if (!f.mount->matrix().allFinite()) throw Error(f.source, "the scan's sensorPose is not finite");
  if (f.scan.empty() && !I.opts.allow_empty_scans)
    throw Error(f.source, "scan " + f.stem + " is empty (0 valid points)");
  if (cur.keyframe_pose) {  // a simplemap's keyframe
    f.scan.pose = toIsometry(*cur.keyframe_pose + cur.sensor_pose);
    f.scan.has_pose = true;
    if (!f.scan.pose.matrix().allFinite())
      throw Error(f.source, "the keyframe's pose is not finite");
  } else if (const Item* p = I.nearest(Item::kPose, cur.t, I.opts.pose_time_tolerance, end)) {
    f.scan.pose = toIsometry(p->robot_pose + cur.sensor_pose);  // robot pose (+) sensor pose
    f.scan.has_pose = true;
    if (!f.scan.pose.matrix().allFinite())
      throw Error(I.path + " " + I.where(p->entry), "the robot pose is not finite");
  } else {
    f.scan.pose = toIsometry(cur.sensor_pose);
  }
  // Odometry (GICP's initial guess): an odometry observation near in time, else the actions.
  if (const Item* o = I.nearest(Item::kOdometry, cur.t, I.opts.pose_time_tolerance, end)) {
    f.odometry = toIsometry(o->robot_pose + cur.sensor_pose);
    if (!f.odometry->matrix().allFinite())
      throw Error(I.path + " " + I.where(o->entry), "the odometry is not finite");
  } else if (cur.action_odometry) {
    f.odometry = toIsometry(*cur.action_odometry + cur.sensor_pose);
    if (!f.odometry->matrix().allFinite())
      throw Error(f.source, "the odometry actions before this scan sum to a non-finite pose");
  }
  // A simplemap's image goes with its keyframe's scan (its times may be missing).
  const auto of_keyframe = I.keyframes ? std::optional<std::size_t>(cur.entry) : std::nullopt;
  if (const Item* im =
          I.nearest(Item::kImage, cur.t, I.opts.image_time_tolerance, end, of_keyframe)) {
    if (!I.camera) I.learnCamera(*im->img, cur.sensor_pose);
    f.image = I.toImage(*im);
  }
  I.buf.erase(I.buf.begin(), I.buf.begin() + static_cast<std::ptrdiff_t>(*s) + 1);
  return f;
}

std::optional<PinholeCamera> RawlogSource::camera() const {
  return impl_->camera;
}

std::size_t RawlogSource::skippedObservations() const {
  return impl_->skipped;
}

const std::string& RawlogSource::lidarLabel() const {
  return impl_->lidar;
}

const std::string& RawlogSource::cameraLabel() const {
  return impl_->cam;
}

const std::map<std::string, std::size_t>& RawlogSource::otherLidars() const {
  return impl_->other_lidars;
}

const std::map<std::string, std::size_t>& RawlogSource::otherCameras() const {
  return impl_->other_cameras;
}

std::size_t RawlogSource::scansTimedBack() const {
  return impl_->timed_back;
}

const std::string& RawlogSource::firstTimedBack() const {
  return impl_->first_timed_back;
}

bool RawlogSource::isSimplemap() const {
  return impl_->keyframes;
}

const std::set<std::string>& RawlogSource::externalFolders() const {
  return impl_->external_dirs;
}

bool isSimplemapName(const std::string& path) {
  const std::string name = fs::path(path).filename().string();
  for (const std::string ext : {".simplemap", ".simplemap.gz"})
    if (name.size() > ext.size() && name.compare(name.size() - ext.size(), ext.size(), ext) == 0)
      return true;
  return false;
}

std::vector<ExternalFile> externalFiles(const ::mrpt::obs::CObservation& obs,
                                        const std::string& file_of, const std::string& where) {
  using namespace ::mrpt::obs;
  std::vector<ExternalFile> out;
  // MRPT resolves a stored name by an assertion (a name of 2 characters or fewer is none): its
  // message names neither the file nor the entry.
  const auto add = [&](const std::string& what, const std::string& name, auto&& resolve) {
    try {
      out.push_back({resolve(), what});
    } catch (const std::exception& e) {
      throw Error(file_of, where + ": the " + what + "'s external file name \"" + name +
                               "\" cannot be resolved (" + briefMessage(e) + ")");
    }
  };
  if (const auto* pc = dynamic_cast<const CObservationPointCloud*>(&obs)) {
    if (pc->isExternallyStored())
      add("scan", pc->getExternalStorageFile(),
          [&] { return ::mrpt::io::lazy_load_absolute_path(pc->getExternalStorageFile()); });
  } else if (const auto* r = dynamic_cast<const CObservation3DRangeScan*>(&obs)) {
    if (r->hasRangeImage && r->rangeImage_isExternallyStored())
      add("range image", r->rangeImage_getExternalStorageFile(""),
          [&] { return r->rangeImage_getExternalStorageFileAbsolutePath(""); });
    if (r->hasPoints3D && r->points3D_isExternallyStored())
      add("scan", r->points3D_getExternalStorageFile(),
          [&] { return r->points3D_getExternalStorageFileAbsolutePath(); });
  } else if (const auto* im = dynamic_cast<const CObservationImage*>(&obs)) {
    if (im->image.isExternallyStored())
      add("image", im->image.getExternalStorageFile(),
          [&] { return im->image.getExternalStorageFileAbsolutePath(); });
  }
  return out;
}

Error missingExternalFile(const std::string& file_of, const std::string& where,
                          const ExternalFile& f) {
  return Error(file_of, where + ": the " + f.what + "'s external file " + f.path +
                            " does not exist (relative paths are read from " +
                            ::mrpt::io::getLazyLoadPathBase() + ")");
}

void loadSimplemap(const std::string& path, ::mrpt::maps::CSimpleMap& out) {
  registerClasses();
  ::mrpt::io::CFileGZInputStream file;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec) || !file.open(path))
    throw Error(path, "cannot be opened as a simplemap (no such file, or not a file)");
  PeekStream in(file);
  try {
    checkObject(in, path, "is", mostBytesIn(path));
    auto arch = ::mrpt::serialization::archiveFrom(in);
    arch >> out;
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    if (in.corrupt()) throw Error(path, CorruptCompressedData().what());
    if (!in.refused().empty()) throw Error(path, "holds " + in.refused());
    throw Error(path, "is not a simplemap MRPT can read (cut short, corrupt, or another file): " +
                          briefMessage(e));
  }
}

std::string useExternalFilesFolderOf(const std::string& file) {
  // CRawlog::detectImagesDirectory's names, in its order (it does not see folders in MRPT 2.5.8).
  const fs::path beside = fs::path(file).parent_path();
  const std::string stem = fs::path(file).stem().string();
  std::error_code ec;
  for (const std::string& name :
       {stem + "_Images", stem + "_images", stem + "_IMAGES", std::string("Images")})
    if (fs::is_directory(beside / name, ec)) {
      ::mrpt::io::setLazyLoadPathBase((beside / name).string());
      return (beside / name).string();
    }
  return {};
}

std::string timedBackWarning(const RawlogSource& rawlog) {
  const std::size_t n = rawlog.scansTimedBack();
  if (n == 0) return {};
  return std::to_string(n) + (n == 1 ? " scan is" : " scans are") +
         " timed earlier than the scan before (the first: " + rawlog.firstTimedBack() +
         "); the scans are taken in file order, and such a scan is not de-skewed";
}

std::string labelCounts(const std::map<std::string, std::size_t>& counts) {
  std::string s;
  for (const auto& [label, n] : counts)
    s += (s.empty() ? "'" : ", '") + label + "' (" + std::to_string(n) + ")";
  return s;
}

}  // namespace cleanmap::mrpt
