// Data and config folders found at run time (artms/io/paths.hpp): the
// environment override, then beside the executable (the build tree has
// build/share/artms/{data,config} like an install).
#include "artms/io/paths.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

namespace artms::io {
namespace {

namespace fs = std::filesystem;

// Sets (or unsets, for nullopt) an environment variable for one scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::optional<std::string>& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value) {
      setenv(name, value->c_str(), 1);
    } else {
      unsetenv(name);
    }
  }
  ~ScopedEnv() {
    if (old_) {
      setenv(name_, old_->c_str(), 1);
    } else {
      unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

TEST(Paths, EnvironmentOverrideIsUsedWhenItHoldsTheFiles) {
  const ScopedEnv d("ARTMS_DATA_DIR", std::string(ARTMS_DATA_DIR) + "/");
  const ScopedEnv c("ARTMS_CONFIG_DIR", std::string(ARTMS_CONFIG_DIR));
  EXPECT_EQ(fs::path(data_dir()), fs::path(ARTMS_DATA_DIR).lexically_normal());
  EXPECT_FALSE(ends_with(data_dir(), "/"));
  EXPECT_EQ(fs::path(config_dir()), fs::path(ARTMS_CONFIG_DIR).lexically_normal());
}

TEST(Paths, AWrongOverrideIsAnErrorNamingIt) {
  const ScopedEnv d("ARTMS_DATA_DIR", std::string(ARTMS_CONFIG_DIR));  // no gravity/ there
  try {
    (void)data_dir();
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("ARTMS_DATA_DIR=" + std::string(ARTMS_CONFIG_DIR)), std::string::npos) << what;
    EXPECT_NE(what.find("gravity/GGM01S.gfc"), std::string::npos) << what;
  }
  const ScopedEnv c("ARTMS_CONFIG_DIR", "/nonexistent/artms/config");
  EXPECT_THROW((void)config_dir(), std::runtime_error);
}

TEST(Paths, WithoutTheEnvironmentTheFoldersBesideTheExecutableAreFound) {
  // This test runs from <build>/bin: <build>/share/artms/{data,config}.
  const ScopedEnv d("ARTMS_DATA_DIR", std::nullopt);
  const ScopedEnv c("ARTMS_CONFIG_DIR", std::string());  // empty counts as unset
  const std::string data = data_dir(), config = config_dir();
  EXPECT_TRUE(ends_with(data, "share/artms/data")) << data;
  EXPECT_TRUE(ends_with(config, "share/artms/config")) << config;
  EXPECT_TRUE(fs::is_regular_file(data + "/gravity/GGM01S.gfc"));
  EXPECT_TRUE(fs::is_regular_file(data + "/stars/bsc5.dat"));
  EXPECT_TRUE(fs::is_regular_file(config + "/cyclonedds-loopback.xml"));
  EXPECT_TRUE(fs::is_regular_file(config + "/cameras/nst.yaml"));
  const fs::path exe = fs::read_symlink("/proc/self/exe");
  EXPECT_EQ(fs::path(data), (exe.parent_path() / ".." / "share" / "artms" / "data").lexically_normal());
}

}  // namespace
}  // namespace artms::io
